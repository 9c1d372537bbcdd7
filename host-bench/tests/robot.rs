//! Robot description files: the seed robots in `robots/` load and match their papers, and bad
//! files are refused with the key and the line (fixtures in `tests/data/robots/`).

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use host_bench::formats::robot::{AbsMeasures, Robot, RobotError};
use robot_math::carriage::CarriageGeometry;
use robot_math::omni3::Omni3;
use robot_math::wheel::Wheel;

fn robots_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots")
}

fn seed(file: &str) -> Robot {
    let path = robots_dir().join(file);
    Robot::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

// ---------------------------------------------------------------------------------------------
// The seed robots

#[test]
fn every_robot_file_loads_and_is_named_after_its_file() {
    let mut names: Vec<String> = std::fs::read_dir(robots_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| {
            let robot = Robot::load(&p).unwrap_or_else(|e| panic!("{e}"));
            let stem = p.file_stem().unwrap().to_str().unwrap().to_string();
            assert_eq!(robot.name, stem, "{}", p.display());
            assert!(!robot.description.is_empty(), "{}", p.display());
            stem
        })
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "diff-wide",
            "omni4-ls",
            "seed000-0.1mm",
            "seed000-0.4mm",
            "seed000-0.8mm",
            "seed001",
            "seed002",
            "seed002-as-built",
            "seed003",
            "seed004",
            "seed004-as-built",
            "skewed3"
        ]
    );
}

#[test]
fn the_master_drives_seed_002s_chassis_and_seed_004s_omni_wheels() {
    use protocol::serial::DriveKind;
    let g = seed("seed002.toml").drive_geometry().unwrap();
    assert_eq!(
        g.kind,
        DriveKind::OffsetDiff {
            y_left_um: 150_000,
            y_right_um: -150_000,
            offset_um: 150_000
        }
    );
    assert_eq!(g.v_max_um_s, 800_000);
    // The file and the boards' power-on robot are the same robot.
    let seed004 = seed("seed004.toml");
    assert_eq!(
        seed004.drive_geometry().unwrap(),
        firmware_master::drive_setup::SEED_004_DRIVE
    );
    assert_eq!(
        seed004.odometry_layout().unwrap(),
        robot_math::odometry::Layout::SEED_004
    );
    // An axle without a tracked point, or with more wheels than the master drives.
    for file in ["seed001.toml", "omni4-ls.toml", "seed000-0.1mm.toml"] {
        let e = seed(file).drive_geometry().unwrap_err().to_string();
        assert!(
            e.contains("robot seed0") || e.contains("robot omni4"),
            "{file}: {e}"
        );
    }
    assert!(seed("seed001.toml")
        .drive_geometry()
        .unwrap_err()
        .to_string()
        .contains("[tracked_point]"));
}

#[test]
fn a_tracked_point_on_the_axle_is_refused_where_it_is() {
    let text = "format = \"omnibench robot v1\"\nname = \"x\"\n[tracked_point]\nx_m = 0\n";
    let e = parse(text).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(4), Some("tracked_point.x_m"))
    );
    assert!(e.message.contains("l != 0"), "{e}");
}

#[test]
fn seed000_is_a_20cm_triangle_of_wheels_turned_45_degrees_from_their_edges() {
    for (file, step) in [
        ("seed000-0.1mm.toml", 0.0001),
        ("seed000-0.4mm.toml", 0.0004),
        ("seed000-0.8mm.toml", 0.0008),
    ] {
        let r = seed(file);
        assert_eq!(r.encoders.len(), 3, "{file}");
        assert!(
            r.carriage.is_none() && r.absolute_encoders.is_empty() && r.drive_wheels.is_empty()
        );
        let names: Vec<&str> = r.encoders.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["A", "B", "C"]);
        let w: Vec<Wheel> = r.encoder_wheels();
        for (i, e) in r.encoders.iter().enumerate() {
            // Centred on the body origin: circumradius of a 0.2 m equilateral triangle.
            let d = e.wheel.x.hypot(e.wheel.y);
            assert!(close(d, 0.2 / 3f64.sqrt(), 1e-9), "{file} {i}: {d}");
            // 20 cm sides.
            let n = &w[(i + 1) % 3];
            let side = (n.x - e.wheel.x).hypot(n.y - e.wheel.y);
            assert!(close(side, 0.2, 1e-9), "{file} {i}: side {side}");
            // Rolling direction = its edge (A→B, B→C, C→A) turned 45° counter-clockwise.
            let (ex, ey) = ((n.x - e.wheel.x) / side, (n.y - e.wheel.y) / side);
            let turn = (ex * e.wheel.uy - ey * e.wheel.ux).atan2(ex * e.wheel.ux + ey * e.wheel.uy);
            assert!(close(turn, PI / 4.0, 1e-9), "{file} {i}: turned {turn}");
            // Unit direction.
            assert!(close(e.wheel.ux.hypot(e.wheel.uy), 1.0, 1e-12));
            assert_eq!(e.metres_per_count, step, "{file} {i}");
        }
        // Body +x is along AC (the paper's heading θ is the angle of AC), B on the left.
        assert!(
            close(w[2].y - w[0].y, 0.0, 1e-12) && w[2].x > w[0].x,
            "{file}"
        );
        assert!(w[1].y > 0.0, "{file}");
        // 120° symmetry: each wheel is the previous one turned by −120° (A, B, C clockwise).
        let rot = |wh: &Wheel, a: f64| {
            let (s, c) = a.sin_cos();
            Wheel {
                x: c * wh.x - s * wh.y,
                y: s * wh.x + c * wh.y,
                ux: c * wh.ux - s * wh.uy,
                uy: s * wh.ux + c * wh.uy,
            }
        };
        for i in 0..3 {
            let (a, b) = (rot(&w[i], -2.0 * PI / 3.0), w[(i + 1) % 3]);
            assert!(
                close(a.x, b.x, 1e-9)
                    && close(a.y, b.y, 1e-9)
                    && close(a.ux, b.ux, 1e-12)
                    && close(a.uy, b.uy, 1e-12),
                "{file}: {a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn seed001_is_a_differential_drive_with_0_4mm_per_count() {
    let r = seed("seed001.toml");
    assert_eq!(r.encoders.len(), 2);
    let (l, rt) = (&r.encoders[0], &r.encoders[1]);
    for e in [l, rt] {
        assert_eq!(e.metres_per_count, 0.0004, "0.04 cm per pulse");
        assert!(close(e.wheel.ux, 1.0, 1e-15) && close(e.wheel.uy, 0.0, 1e-15));
        assert_eq!(e.wheel.x, 0.0);
    }
    // On one axle, centred on the reference point; track width 0.30 m (assumed).
    assert_eq!(l.wheel.y, 0.15);
    assert_eq!(rt.wheel.y, -0.15);
    assert_eq!(r.drive_wheels.len(), 2);
    for (d, e) in r.drive_wheels.iter().zip(&r.encoders) {
        assert_eq!(d.wheel, e.wheel);
    }
    assert!(r.carriage.is_none() && r.carriage_geometry().is_none());
}

#[test]
fn seed003_drive_wheel_rows_are_omni3s() {
    let r = seed("seed003.toml");
    assert!(r.encoders.is_empty(), "the paper gives no encoders");
    let omni = Omni3::wheels(0.22);
    assert_eq!(r.drive_wheels.len(), 3);
    let s60 = (PI / 3.0).sin();
    let c60 = (PI / 3.0).cos();
    let paper = [[0.0, 1.0, 0.22], [-s60, -c60, 0.22], [s60, -c60, 0.22]];
    for ((d, o), p) in r.drive_wheels.iter().zip(&omni).zip(&paper) {
        assert_eq!(d.v_max_m_s, 1.0);
        let (a, b) = (d.wheel.row(), o.row());
        for k in 0..3 {
            assert!(close(a[k], b[k], 1e-12), "{a:?} vs omni3 {b:?}");
            assert!(close(a[k], p[k], 1e-12), "{a:?} vs paper {p:?}");
        }
    }
    // And it drives like Omni3: the same wheel speeds for a twist.
    let o = Omni3::new(0.22, 1.0).unwrap();
    let t = robot_math::Twist::new(0.3, -0.2, 1.1);
    for (d, s) in r.drive_wheels.iter().zip(o.wheel_speeds(t)) {
        assert!(close(d.wheel.rolling_speed(t), s, 1e-12));
    }
}

#[test]
fn seed004_carriage_geometry_is_robot_maths_seed_004() {
    let r = seed("seed004.toml");
    let g = r.carriage_geometry().expect("seed 004 has a carriage");
    let s = CarriageGeometry::SEED_004;
    assert_eq!(g.wheel_base, s.wheel_base);
    assert_eq!(g.trail, s.trail);
    assert_eq!(g.metres_per_count, s.metres_per_count);
    assert_eq!(g.abs_bits, s.abs_bits);
    assert_eq!(g, s);
    // 50 mm wheels, 1200 P/R ×4: 32.7 µm per count.
    assert!(close(r.encoders[0].metres_per_count, 32.72e-6, 0.01e-6));
    // Wheel 0 left, wheel 1 right, both rolling along the carriage's +x.
    assert!(r.encoders[0].wheel.y > 0.0 && r.encoders[1].wheel.y < 0.0);
    for e in &r.encoders {
        assert_eq!(e.wheel.row()[0], 1.0);
    }
    // The E6CP-AG5C: 8-bit inverted Gray code, reading the swivel.
    let a = r.absolute_encoder(AbsMeasures::CarriageSwivel).unwrap();
    assert_eq!((a.bits, a.gray, a.inverted), (8, true, true));
    assert_eq!(a.positions(), 256);
    // Position 64 (a quarter turn): Gray 0b0110_0000, shown active-low on the pins.
    assert_eq!(a.levels(64), !0b0110_0000u16 & 0xFF);
    assert_eq!(a.decode(!0b0110_0000u16 & 0xFF), 64);
    // Seed 003's drive.
    for (d, o) in r.drive_wheels.iter().zip(Omni3::wheels(0.22)) {
        let (a, b) = (d.wheel.row(), o.row());
        assert!((0..3).all(|k| close(a[k], b[k], 1e-12)), "{a:?} vs {b:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Bad files

fn bad(file: &str) -> (PathBuf, RobotError) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/robots")
        .join(file);
    match Robot::load(&path) {
        Ok(_) => panic!("{file} loaded"),
        Err(e) => (path, e),
    }
}

/// Asserts the error names `key` at `line`, in the fields and in the message, and says `what`.
fn assert_error(file: &str, key: &str, line: usize, what: &str) {
    let (path, e) = bad(file);
    let shown = e.to_string();
    assert_eq!(e.key.as_deref(), Some(key), "{shown}");
    assert_eq!(e.line, Some(line), "{shown}");
    assert!(
        shown.starts_with(&format!("{}:{line}:", path.display())),
        "{shown}"
    );
    assert!(shown.contains(&format!("key `{key}`")), "{shown}");
    assert!(shown.contains(what), "{shown}");
}

#[test]
fn bad_unknown_key() {
    assert_error(
        "unknown-key.toml",
        "encoders[0].metres_per_cont",
        9,
        "unknown field",
    );
}

#[test]
fn bad_wrong_type() {
    assert_error(
        "wrong-type.toml",
        "encoders[1].y_m",
        14,
        "expected a number",
    );
}

#[test]
fn bad_negative_metres_per_count() {
    let (path, e) = bad("negative-metres-per-count.toml");
    assert_eq!(
        e.to_string(),
        format!(
            "{}:16:20: key `encoders[1].metres_per_count`: a count must be 1e-7 to 0.0625 m \
             of wheel travel, got -1 m",
            path.display()
        )
    );
}

#[test]
fn bad_both_count_forms() {
    assert_error(
        "both-count-forms.toml",
        "encoders[0].metres_per_count",
        9,
        "not both",
    );
}

#[test]
fn bad_missing_format() {
    assert_error("missing-format.toml", "format", 1, "missing");
}

#[test]
fn bad_degenerate_three_wheels() {
    assert_error("degenerate-three.toml", "encoders", 6, "rank < 3");
}

#[test]
fn bad_two_wheels_not_on_an_axle() {
    assert_error("not-on-axle.toml", "encoders", 5, "one axle");
}

#[test]
fn bad_carriage_without_swivel_encoder() {
    assert_error(
        "carriage-without-swivel.toml",
        "carriage",
        5,
        "carriage_swivel",
    );
}

#[test]
fn bad_swivel_encoder_without_carriage() {
    assert_error(
        "swivel-without-carriage.toml",
        "absolute_encoders[0].measures",
        20,
        "needs a [carriage]",
    );
}

#[test]
fn bad_absolute_encoder_bits() {
    assert_error(
        "bits-out-of-range.toml",
        "absolute_encoders[0].bits",
        7,
        "1 to 16",
    );
}

#[test]
fn bad_toml_syntax() {
    assert_error("syntax-error.toml", "encoders[0].name", 6, "TOML syntax");
}

#[test]
fn a_missing_file_is_named() {
    let path = Path::new("no/such/robot.toml");
    let e = Robot::load(path).unwrap_err();
    assert_eq!((e.line, e.key.as_deref()), (None, None));
    assert!(
        e.to_string().starts_with("no/such/robot.toml: cannot read"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// Rules, on small inline files

const HEAD: &str = "format = \"omnibench robot v1\"\nname = \"t\"\n";

fn encoder(name: &str, x: f64, y: f64, dir: f64) -> String {
    format!(
        "[[encoders]]\nname = \"{name}\"\nx_m = {x:?}\ny_m = {y:?}\ndirection_deg = {dir:?}\nmetres_per_count = 0.0001\n"
    )
}

const SWIVEL: &str =
    "[[absolute_encoders]]\nname = \"s\"\nbits = 8\ncode = \"gray\"\nmeasures = \"carriage_swivel\"\n";

fn parse(text: &str) -> Result<Robot, RobotError> {
    Robot::parse(text, Path::new("inline.toml"))
}

fn err_at(text: &str) -> (Option<String>, Option<usize>) {
    let e = parse(text).expect_err("should be refused");
    (e.key, e.line)
}

#[test]
fn carriage_wheels_must_be_left_then_right_on_the_axle() {
    let carriage = "[carriage]\ntrail_m = 0.06\n";
    let good = format!(
        "{HEAD}{carriage}{}{}{SWIVEL}",
        encoder("l", 0.0, 0.1, 0.0),
        encoder("r", 0.0, -0.1, 0.0)
    );
    assert!(parse(&good).unwrap().carriage_geometry().is_some());
    // Right wheel first (line 3 + 2 + 4 = encoders[0].y_m).
    let swapped = format!(
        "{HEAD}{carriage}{}{}{SWIVEL}",
        encoder("r", 0.0, -0.1, 0.0),
        encoder("l", 0.0, 0.1, 0.0)
    );
    assert_eq!(err_at(&swapped), (Some("encoders[0].y_m".into()), Some(8)));
    // Not rolling along the carriage's +x.
    let turned = format!(
        "{HEAD}{carriage}{}{}{SWIVEL}",
        encoder("l", 0.0, 0.1, 0.0),
        encoder("r", 0.0, -0.1, 90.0)
    );
    assert_eq!(
        err_at(&turned),
        (Some("encoders[1].direction_deg".into()), Some(15))
    );
    // Three encoders on a carriage.
    let three = format!(
        "{HEAD}{carriage}{}{}{}{SWIVEL}",
        encoder("l", 0.0, 0.1, 0.0),
        encoder("r", 0.0, -0.1, 0.0),
        encoder("x", 0.0, 0.0, 0.0)
    );
    assert_eq!(err_at(&three), (Some("carriage".into()), Some(3)));
    // Asymmetric about the axle midpoint.
    let off = format!(
        "{HEAD}{carriage}{}{}{SWIVEL}",
        encoder("l", 0.0, 0.1, 0.0),
        encoder("r", 0.0, -0.12, 0.0)
    );
    assert_eq!(err_at(&off), (Some("encoders[1].y_m".into()), Some(14)));
    // A trail that is not positive.
    let no_trail = good.replace("trail_m = 0.06", "trail_m = 0");
    assert_eq!(
        err_at(&no_trail),
        (Some("carriage.trail_m".into()), Some(4))
    );
}

#[test]
fn travel_per_count_forms() {
    let base = format!("{HEAD}{}", encoder("a", 0.0, 0.1, 0.0));
    let only_counts = base.replace("metres_per_count = 0.0001", "counts_per_rev = 2000");
    assert_eq!(
        err_at(&only_counts),
        (Some("encoders[0].wheel_diameter_m".into()), Some(8))
    );
    let neither = base.replace("metres_per_count = 0.0001\n", "");
    assert_eq!(
        err_at(&neither),
        (Some("encoders[0].metres_per_count".into()), Some(3))
    );
    let fractional = base.replace(
        "metres_per_count = 0.0001",
        "counts_per_rev = 2000.5\nwheel_diameter_m = 0.05",
    );
    assert_eq!(
        err_at(&fractional),
        (Some("encoders[0].counts_per_rev".into()), Some(8))
    );
    let two = format!(
        "{HEAD}{}{}",
        encoder("l", 0.0, 0.1, 0.0),
        encoder("r", 0.0, -0.1, 0.0)
    )
    .replace(
        "metres_per_count = 0.0001",
        "counts_per_rev = 2000\nwheel_diameter_m = 0.05",
    );
    let r = parse(&two).unwrap();
    assert_eq!(r.encoders[1].metres_per_count, PI * 0.05 / 2000.0);
}

#[test]
fn encoder_counts_and_layouts() {
    // One encoder alone.
    let one = format!("{HEAD}{}", encoder("a", 0.0, 0.1, 0.0));
    assert_eq!(err_at(&one), (Some("encoders".into()), Some(3)));
    // Three wheels whose rolling lines meet in one point (all radial): blind to spin.
    let radial: String = (0..3)
        .map(|i| {
            let a = i as f64 * 120.0;
            let (s, c) = a.to_radians().sin_cos();
            encoder(&format!("w{i}"), 0.1 * c, 0.1 * s, a)
        })
        .collect();
    assert_eq!(
        err_at(&format!("{HEAD}{radial}")),
        (Some("encoders".into()), Some(3))
    );
    // Four wheels, redundant: fine (least squares).
    let four: String = (0..4)
        .map(|i| {
            let a = i as f64 * 90.0;
            let (s, c) = a.to_radians().sin_cos();
            encoder(&format!("w{i}"), 0.1 * c, 0.1 * s, a + 90.0)
        })
        .collect();
    assert_eq!(parse(&format!("{HEAD}{four}")).unwrap().encoders.len(), 4);
    // Duplicate names.
    let dup = format!(
        "{HEAD}{}{}",
        encoder("a", 0.0, 0.1, 0.0),
        encoder("a", 0.0, -0.1, 0.0)
    );
    assert_eq!(err_at(&dup), (Some("encoders[1].name".into()), Some(10)));
    // No sensors at all is a drive-only description, like seed 003.
    assert!(parse(HEAD).unwrap().encoders.is_empty());
}

#[test]
fn mangled_seed_files_are_refused_with_a_line_never_a_panic() {
    for file in ["seed000-0.1mm.toml", "seed001.toml", "seed004.toml"] {
        let text = std::fs::read_to_string(robots_dir().join(file)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for i in 0..lines.len() {
            let mut variants = vec![];
            let mut dropped = lines.clone();
            dropped.remove(i);
            variants.push(dropped.join("\n"));
            if let Some((k, _)) = lines[i].split_once(" = ") {
                for v in ["\"x\"", "-1", "0", "nan", "[", "true", "1e400"] {
                    let mut changed = lines.clone();
                    let new = format!("{k} = {v}");
                    changed[i] = &new;
                    variants.push(changed.join("\n"));
                }
            }
            for v in variants {
                if let Err(e) = parse(&v) {
                    let line = e.line.unwrap_or_else(|| panic!("{file} line {i}: {e}"));
                    assert!(line <= lines.len() + 1, "{file}: {e}");
                    if !e.message.starts_with("TOML syntax") {
                        assert!(e.key.is_some(), "{file} line {}: {e}", i + 1);
                    }
                }
            }
        }
    }
}
