//! Tick stream files (format version 1, docs/tick-stream.md): round trips, files written by
//! other programs, and every class of malformed input.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use host_bench::formats::tickstream::{self, Event, ReadError, TickStream, MAGIC};

const HEADER: &str = "t_ns,kind,id,value,x_m,y_m,theta_rad";

/// A fresh, empty directory for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("tickstream-tests")
        .join(test);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/tickstreams")
        .join(name)
}

fn sample() -> TickStream {
    TickStream {
        robot: Some("../robots/seed000.toml".into()),
        comments: vec![
            "generator: test, seed 7".into(),
            String::new(),
            "  indented".into(),
        ],
        events: vec![
            Event::Truth {
                t_ns: 0,
                x_m: 0.0,
                y_m: -0.0,
                theta_rad: std::f64::consts::PI,
            },
            Event::Abs {
                t_ns: 0,
                encoder: 0,
                code: 37,
            },
            Event::Tick {
                t_ns: 1_534_000,
                encoder: 0,
                step: 1,
            },
            Event::Tick {
                t_ns: 1_534_000,
                encoder: 65535,
                step: -1,
            },
            Event::Abs {
                t_ns: 2_000_000,
                encoder: 2,
                code: u32::MAX,
            },
            Event::Truth {
                t_ns: 3_000_000,
                x_m: 0.1 + 0.2,
                y_m: -1e-300,
                theta_rad: 1.0 / 3.0,
            },
            Event::Truth {
                t_ns: u64::MAX,
                x_m: tickstream::MAX_TRUTH_COORDINATE_M, // the largest a reader takes
                y_m: f64::MIN_POSITIVE / 8.0,            // subnormal
                theta_rad: -123456.789e-1,
            },
        ],
    }
}

/// Reads `text` as a file called `ticks.csv`, expecting an error.
fn read_err(text: &str) -> ReadError {
    read_bytes_err(text.as_bytes())
}

fn read_bytes_err(bytes: &[u8]) -> ReadError {
    match tickstream::read_from(bytes, Path::new("ticks.csv")) {
        Ok(s) => panic!("expected an error, read {s:?}"),
        Err(e) => e,
    }
}

fn read_ok(text: &str) -> TickStream {
    tickstream::read_from(text.as_bytes(), Path::new("ticks.csv")).unwrap_or_else(|e| panic!("{e}"))
}

/// Asserts the error is on `line` and its message contains `phrase`.
#[track_caller]
fn assert_err(e: &ReadError, line: Option<u64>, phrase: &str) {
    assert_eq!(e.line, line, "wrong line in: {e}");
    assert!(e.message.contains(phrase), "{phrase:?} not in: {e}");
    assert_eq!(e.path, Path::new("ticks.csv"), "{e}");
}

/// A valid stream's text with `rows` after the header.
fn stream_text(rows: &[&str]) -> String {
    let mut s = format!("{MAGIC}\n{HEADER}\n");
    for r in rows {
        s.push_str(r);
        s.push('\n');
    }
    s
}

// ---- round trips -------------------------------------------------------------------------

#[test]
fn round_trip_plain_keeps_every_kind_comment_and_bit() {
    let dir = scratch("round_trip_plain");
    let path = dir.join("ticks.csv");
    let s = sample();
    tickstream::write(&path, &s).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    assert!(text.starts_with(&format!("{MAGIC}\n# robot: ../robots/seed000.toml\n")));
    let back = tickstream::read(&path).unwrap();
    assert_eq!(back, s);
    // Bit-exact floats (PartialEq would let -0.0 == 0.0 through).
    for (a, b) in back.events.iter().zip(&s.events) {
        if let (
            Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            },
            Event::Truth {
                x_m: x2,
                y_m: y2,
                theta_rad: t2,
                ..
            },
        ) = (a, b)
        {
            assert_eq!(x_m.to_bits(), x2.to_bits());
            assert_eq!(y_m.to_bits(), y2.to_bits());
            assert_eq!(theta_rad.to_bits(), t2.to_bits());
        }
    }
    assert_eq!(
        entries(&dir),
        ["ticks.csv"],
        "only the stream itself is left"
    );
}

#[test]
fn round_trip_gzip_compresses_and_reads_back() {
    let dir = scratch("round_trip_gzip");
    let path = dir.join("ticks.csv.gz");
    let s = sample();
    tickstream::write(&path, &s).unwrap();
    let bytes = fs::read(&path).unwrap();
    assert_eq!(&bytes[..2], &[0x1f, 0x8b], "not gzip");
    assert_eq!(tickstream::read(&path).unwrap(), s);
    // The magic bytes alone are enough: the same data under a plain name, and from memory.
    let renamed = dir.join("ticks.csv");
    fs::rename(&path, &renamed).unwrap();
    assert_eq!(tickstream::read(&renamed).unwrap(), s);
    assert_eq!(tickstream::read_from(&bytes[..], &renamed).unwrap(), s);
}

#[test]
fn round_trip_of_an_empty_stream() {
    let dir = scratch("round_trip_empty");
    let path = dir.join("empty.csv");
    tickstream::write(&path, &TickStream::default()).unwrap();
    assert_eq!(
        fs::read_to_string(&path).unwrap(),
        format!("{MAGIC}\n{HEADER}\n")
    );
    assert_eq!(tickstream::read(&path).unwrap(), TickStream::default());
}

#[test]
fn write_replaces_an_existing_file() {
    let dir = scratch("write_replaces");
    let path = dir.join("ticks.csv");
    fs::write(&path, "old").unwrap();
    tickstream::write(&path, &sample()).unwrap();
    assert_eq!(tickstream::read(&path).unwrap(), sample());
}

#[test]
fn columns_in_another_order_and_unknown_columns_are_read_by_name() {
    let s = read_ok(&format!(
        "{MAGIC}\n\
         note,theta_rad,value,y_m,kind,x_m,id,t_ns,extra\n\
         hello,0.5,,2.5,truth,1.5,,10,x\n\
         ,,-1,,tick,,4,20,\n\
         \"a, b\",,99,,abs,,1,30,7\n"
    ));
    assert_eq!(
        s.events,
        vec![
            Event::Truth {
                t_ns: 10,
                x_m: 1.5,
                y_m: 2.5,
                theta_rad: 0.5
            },
            Event::Tick {
                t_ns: 20,
                encoder: 4,
                step: -1
            },
            Event::Abs {
                t_ns: 30,
                encoder: 1,
                code: 99
            },
        ]
    );
}

#[test]
fn comments_blank_lines_and_whitespace_anywhere() {
    let s = read_ok(&format!(
        "{MAGIC}   \n\
         \n\
         #first\n\
         # robot:   robots/a b.toml  \n\
         {HEADER}\n\
         \x20 # between rows\n\
         \t\n\
         5 , tick , 0 , +1 , , , \n\
         6,truth,,,1,2,3\n\
         #last"
    ));
    assert_eq!(s.robot.as_deref(), Some("robots/a b.toml"));
    assert_eq!(s.comments, vec!["first", "between rows", "last"]);
    assert_eq!(s.events.len(), 2);
    assert_eq!(s.events[0].t_ns(), 5);
    assert_eq!(s.events[1].t_ns(), 6);
}

#[test]
fn robot_path_is_relative_to_the_stream_file() {
    let s = TickStream {
        robot: Some("../robots/seed000.toml".into()),
        ..TickStream::default()
    };
    assert_eq!(
        s.robot_path(Path::new("runs/a/ticks.csv")),
        Some(PathBuf::from("runs/a/../robots/seed000.toml"))
    );
    assert_eq!(
        s.robot_path(Path::new("ticks.csv")),
        Some(PathBuf::from("../robots/seed000.toml"))
    );
    assert_eq!(TickStream::default().robot_path(Path::new("x/t.csv")), None);
}

#[test]
fn line_numbers_count_comment_blank_and_crlf_lines() {
    let text =
        format!("{MAGIC}\r\n# c\r\n\r\n{HEADER}\r\n1,tick,0,1,,,\r\n# c\r\n\r\n2,tick,0,2,,,\r\n");
    assert_err(
        &read_err(&text),
        Some(8),
        "tick value must be +1 or -1, got 2",
    );
}

#[test]
fn error_display_is_path_line_message() {
    let e = read_err(&stream_text(&["1,tick,0,1,,,", "2,tick,0,2,,,"]));
    assert_eq!(
        e.to_string(),
        "ticks.csv:4: tick value must be +1 or -1, got 2"
    );
    let e = read_err("");
    assert!(e.to_string().starts_with("ticks.csv: empty file"), "{e}");
}

// ---- files written by other programs -----------------------------------------------------

#[test]
fn reads_python_csv_module_style_with_crlf() {
    let path = data("python-crlf.csv");
    let bytes = fs::read(&path).unwrap();
    assert!(
        bytes.windows(2).filter(|w| w == b"\r\n").count() >= 12,
        "the test file must keep its CRLF line endings"
    );
    let s = tickstream::read(&path).unwrap();
    assert_eq!(s.robot.as_deref(), Some("../robots/seed000.toml"));
    assert_eq!(s.comments.len(), 2);
    assert_eq!(s.comments[1], "a comment between rows");
    assert_eq!(
        s.events,
        vec![
            Event::Truth {
                t_ns: 0,
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: 0.0
            },
            Event::Abs {
                t_ns: 0,
                encoder: 0,
                code: 37
            },
            Event::Tick {
                t_ns: 1_534_000,
                encoder: 0,
                step: 1
            },
            Event::Tick {
                t_ns: 1_534_000,
                encoder: 1,
                step: -1
            },
            Event::Abs {
                t_ns: 2_000_000,
                encoder: 0,
                code: 38
            },
            Event::Tick {
                t_ns: 2_500_000,
                encoder: 1,
                step: 1
            },
            Event::Truth {
                t_ns: 3_000_000,
                x_m: 0.0001,
                y_m: -2.5e-5,
                theta_rad: 0.001
            },
        ]
    );
    assert_eq!(s.robot_path(&path), Some(data("../robots/seed000.toml")));
    // The same file gzip-compressed by Python's gzip module.
    assert_eq!(tickstream::read(&data("python-crlf.csv.gz")).unwrap(), s);
}

/// `python-circle.csv` is the output of `python-circle.py`, the example of
/// docs/tick-stream.md with coarser steps: a differential robot driving one
/// counter-clockwise lap of a 0.5 m circle at 0.2 m/s.
#[test]
fn reads_the_documented_python_example() {
    let path = data("python-circle.csv");
    let s = tickstream::read(&path).unwrap();
    assert_eq!(s.robot.as_deref(), Some("diff-drive.toml"));
    let ticks = |enc: u16| {
        s.events
            .iter()
            .filter(|e| matches!(e, Event::Tick { encoder, step: 1, .. } if *encoder == enc))
            .count()
    };
    // One lap: the inner (left) wheel rolls 2π·0.4 m, the outer 2π·0.6 m, in 1 cm counts.
    assert_eq!(ticks(0), 251);
    assert_eq!(ticks(1), 376);
    let truths: Vec<_> = s
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            } => Some((x_m, y_m, theta_rad)),
            _ => None,
        })
        .collect();
    assert_eq!(truths.len(), 158);
    for &(x, y, _) in &truths {
        assert!((x.hypot(y - 0.5) - 0.5).abs() < 1e-12, "off the circle");
    }
    // The last truth row is at 15.7 s, just short of the lap (15.708 s), at 0.4 rad/s.
    let (x, y, theta) = *truths.last().unwrap();
    assert!(x.abs() < 0.002 && y.abs() < 1e-5 && (theta - 15.7 * 0.4).abs() < 1e-9);
    assert!(s.events.windows(2).all(|w| w[0].t_ns() <= w[1].t_ns()));
    // The robot file it names (also in the doc) loads, and its encoders are the ones counted.
    let robot = host_bench::formats::robot::Robot::load(&s.robot_path(&path).unwrap())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(robot.encoders.len(), 2);
    assert_eq!(robot.encoders[0].name, "left");
    assert!(robot.encoders[0].wheel.y > 0.0 && robot.encoders[1].wheel.y < 0.0);
}

#[test]
fn reads_a_spreadsheet_export_with_bom_quotes_and_padding() {
    let s = tickstream::read(&data("spreadsheet.csv")).unwrap();
    assert_eq!(s.robot.as_deref(), Some("robot.toml"));
    assert_eq!(s.comments, vec!["exported from a spreadsheet"]);
    assert_eq!(
        s.events,
        vec![
            Event::Truth {
                t_ns: 0,
                x_m: 1.5,
                y_m: -2.0,
                theta_rad: 0.25
            },
            Event::Tick {
                t_ns: 10,
                encoder: 3,
                step: -1
            },
            Event::Abs {
                t_ns: 20,
                encoder: 1,
                code: 255
            },
        ]
    );
}

// ---- writing -----------------------------------------------------------------------------

#[test]
fn write_refuses_an_invalid_stream_and_leaves_nothing() {
    let dir = scratch("write_invalid");
    let tick = |t_ns, step| Event::Tick {
        t_ns,
        encoder: 0,
        step,
    };
    let truth = |x_m| Event::Truth {
        t_ns: 0,
        x_m,
        y_m: 0.0,
        theta_rad: 0.0,
    };
    let cases: Vec<(TickStream, &str)> = vec![
        (
            TickStream {
                events: vec![tick(5, 1), tick(4, 1)],
                ..TickStream::default()
            },
            "non-decreasing time order",
        ),
        (
            TickStream {
                events: vec![tick(5, 2)],
                ..TickStream::default()
            },
            "tick step must be +1 or -1, got 2",
        ),
        (
            TickStream {
                events: vec![truth(f64::NAN)],
                ..TickStream::default()
            },
            "must be finite",
        ),
        (
            TickStream {
                comments: vec!["two\nlines".into()],
                ..TickStream::default()
            },
            "line break",
        ),
        (
            TickStream {
                comments: vec!["robot: x.toml".into()],
                ..TickStream::default()
            },
            "robot line",
        ),
        (
            TickStream {
                comments: vec!["padded, ".into()],
                ..TickStream::default()
            },
            "ends with a comma or whitespace",
        ),
        (
            TickStream {
                robot: Some(" r.toml".into()),
                ..TickStream::default()
            },
            "whitespace",
        ),
    ];
    for (i, (stream, phrase)) in cases.iter().enumerate() {
        let path = dir.join(format!("case{i}.csv.gz"));
        let e = tickstream::write(&path, stream).unwrap_err();
        let chain = format!("{e:#}");
        assert!(chain.contains(phrase), "{phrase:?} not in: {chain}");
        assert!(chain.contains(&path.display().to_string()), "{chain}");
    }
    let left: Vec<_> = fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
}

#[test]
fn failed_write_leaves_no_partial_file() {
    let dir = scratch("write_fails");
    // The target is an existing directory: refused before anything is written.
    let target = dir.join("ticks.csv");
    fs::create_dir(&target).unwrap();
    fs::write(target.join("keep"), "x").unwrap();
    let e = tickstream::write(&target, &sample()).unwrap_err();
    assert!(
        format!("{e:#}").contains("it exists and is not a regular file (a folder)"),
        "{e:#}"
    );
    assert_eq!(entries(&dir), ["ticks.csv"], "a temporary file was left");
    assert_eq!(entries(&target), ["keep"]);
    // A directory that does not exist: nothing can be created, and the error says where.
    let e = tickstream::write(&dir.join("no/such/dir.csv"), &sample()).unwrap_err();
    let chain = format!("{e:#}");
    assert!(chain.contains("no/such/dir.csv"), "{chain}");
    assert!(chain.contains("does not exist"), "{chain}");
}

/// The names in `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

// ---- one test per error class ------------------------------------------------------------

#[test]
fn error_empty_file() {
    assert_err(&read_err(""), None, "empty file");
}

#[test]
fn error_missing_magic_line() {
    assert_err(
        &read_err(&format!("{HEADER}\n1,tick,0,1,,,\n")),
        Some(1),
        "missing magic line",
    );
    assert_err(
        &read_err(&format!("\n{MAGIC}\n{HEADER}\n")),
        Some(1),
        "found an empty line",
    );
    assert_err(
        &read_err("# omnibench tick stream\n"),
        Some(1),
        "missing magic line",
    );
}

#[test]
fn error_unsupported_version() {
    let e = read_err(&format!("# omnibench tick stream v2\n{HEADER}\n"));
    assert_err(&e, Some(1), "unsupported version 2");
    assert_err(
        &read_err("# omnibench tick stream v10  \r\n"),
        Some(1),
        "unsupported version 10",
    );
}

#[test]
fn error_no_header() {
    assert_err(
        &read_err(&format!("{MAGIC}\n# c\n\n")),
        None,
        "no header line",
    );
}

#[test]
fn error_missing_required_column() {
    let e = read_err(&format!("{MAGIC}\n# c\nt_ns,kind,id,value,x_m,theta_rad\n"));
    assert_err(&e, Some(3), "missing column y_m");
    let e = read_err(&format!("{MAGIC}\n0,truth,,,0,0,0\n"));
    assert_err(&e, Some(2), "is the header line missing?");
    // Names are case-sensitive.
    let e = read_err(&format!("{MAGIC}\nT_NS,kind,id,value,x_m,y_m,theta_rad\n"));
    assert_err(&e, Some(2), "missing column t_ns");
}

#[test]
fn error_duplicate_column() {
    let e = read_err(&format!("{MAGIC}\n{HEADER},id\n"));
    assert_err(&e, Some(2), "duplicate column id (fields 3 and 8)");
    // Unknown columns may repeat (spreadsheets pad headers with empty names).
    read_ok(&format!("{MAGIC}\n{HEADER},,,note,note\n"));
}

#[test]
fn error_wrong_field_count() {
    let e = read_err(&stream_text(&["1,tick,0,1,,,", "2,tick,0,1"]));
    assert_err(
        &e,
        Some(4),
        "expected 7 fields as in the header (line 2), found 4",
    );
    let e = read_err(&stream_text(&["1,tick,0,1,,,,"]));
    assert_err(&e, Some(3), "found 8");
}

#[test]
fn error_unterminated_quote() {
    let e = read_err(&stream_text(&["1,tick,0,\"1,,,", ",,,"]));
    assert_err(&e, Some(3), "unterminated quoted field 4");
}

#[test]
fn error_bad_integer() {
    assert_err(
        &read_err(&stream_text(&["1.5,tick,0,1,,,"])),
        Some(3),
        "t_ns must be a whole number of nanoseconds",
    );
    assert_err(
        &read_err(&stream_text(&["-1,tick,0,1,,,"])),
        Some(3),
        "got -1",
    );
    assert_err(
        &read_err(&stream_text(&["18446744073709551616,tick,0,1,,,"])),
        Some(3),
        "t_ns must be",
    );
    assert_err(
        &read_err(&stream_text(&[",tick,0,1,,,"])),
        Some(3),
        "t_ns is empty",
    );
    assert_err(
        &read_err(&stream_text(&["1,tick,65536,1,,,"])),
        Some(3),
        "tick id must be an encoder index from 0 to 65535, got 65536",
    );
    assert_err(
        &read_err(&stream_text(&["1,abs,,5,,,"])),
        Some(3),
        "abs id must be an encoder index from 0 to 65535, got an empty field",
    );
    assert_err(
        &read_err(&stream_text(&["1,abs,0,0x1f,,,"])),
        Some(3),
        "abs value must be a raw code from 0 to 4294967295, got 0x1f",
    );
    assert_err(
        &read_err(&stream_text(&["1,abs,0,4294967296,,,"])),
        Some(3),
        "got 4294967296",
    );
}

#[test]
fn error_bad_float() {
    assert_err(
        &read_err(&stream_text(&["1,truth,,,0.5,abc,0"])),
        Some(3),
        "truth y_m must be a number, got abc",
    );
    assert_err(
        &read_err(&stream_text(&["1,truth,,,0.5,1,"])),
        Some(3),
        "truth theta_rad must be a number, got an empty field",
    );
    assert_err(
        &read_err(&stream_text(&["1,truth,,,\"0,5\",1,2"])),
        Some(3),
        "truth x_m must be a number, got \"0,5\"",
    );
}

#[test]
fn error_nan_or_infinity_in_truth() {
    for bad in ["NaN", "nan", "inf", "-inf", "infinity", "1e999"] {
        let e = read_err(&stream_text(&[
            "0,truth,,,0,0,0",
            &format!("1,truth,,,{bad},0,0"),
        ]));
        assert_err(&e, Some(4), "truth x_m must be finite");
    }
}

#[test]
fn error_unknown_kind() {
    assert_err(
        &read_err(&stream_text(&["1,Tick,0,1,,,"])),
        Some(3),
        "unknown kind Tick (expected tick, abs or truth)",
    );
    assert_err(
        &read_err(&stream_text(&["1,,0,1,,,"])),
        Some(3),
        "kind is empty",
    );
}

#[test]
fn error_decreasing_t_ns() {
    let e = read_err(&stream_text(&[
        "100,tick,0,1,,,",
        "# c",
        "100,abs,0,1,,,",
        "99,tick,0,1,,,",
    ]));
    assert_err(&e, Some(6), "t_ns decreases: 99 after 100 (line 5)");
}

#[test]
fn error_tick_value_not_plus_or_minus_one() {
    for (bad, shown) in [
        ("2", "got 2"),
        ("0", "got 0"),
        ("1.0", "got 1.0"),
        ("", "got an empty field"),
        ("--1", "got --1"),
    ] {
        let e = read_err(&stream_text(&[&format!("1,tick,0,{bad},,,")]));
        assert_err(
            &e,
            Some(3),
            &format!("tick value must be +1 or -1, {shown}"),
        );
    }
}

#[test]
fn error_field_that_must_be_empty() {
    assert_err(
        &read_err(&stream_text(&["1,tick,0,1,0.0,,"])),
        Some(3),
        "x_m must be empty in a tick row, got 0.0",
    );
    assert_err(
        &read_err(&stream_text(&["1,abs,0,1,,,0"])),
        Some(3),
        "theta_rad must be empty in a abs row",
    );
    assert_err(
        &read_err(&stream_text(&["1,truth,0,,0,0,0"])),
        Some(3),
        "id must be empty in a truth row, got 0",
    );
}

#[test]
fn error_second_robot_line() {
    let e = read_err(&format!(
        "{MAGIC}\n# robot: a.toml\n{HEADER}\n#robot: b.toml\n"
    ));
    assert_err(&e, Some(4), "second `# robot:` line (the first is line 2)");
    assert_err(
        &read_err(&format!("{MAGIC}\n# robot:  \n")),
        Some(2),
        "without a path",
    );
}

#[test]
fn error_not_utf8() {
    let mut bytes = stream_text(&["1,tick,0,1,,,"]).into_bytes();
    bytes.extend_from_slice(b"# caf\xe9\n");
    assert_err(
        &read_bytes_err(&bytes),
        Some(4),
        "not valid UTF-8 (bad byte at column 6)",
    );
}

#[test]
fn error_io_names_the_path() {
    let dir = scratch("io_errors");
    let missing = dir.join("missing.csv");
    let e = tickstream::read(&missing).unwrap_err();
    assert_eq!(e.path, missing);
    assert_eq!(e.line, None);
    assert!(
        e.to_string()
            .starts_with(&format!("{}: cannot open", missing.display())),
        "{e}"
    );

    // A directory is not a file.
    let e = tickstream::read(&dir).unwrap_err();
    assert!(e.to_string().contains("cannot"), "{e}");
}

#[test]
fn error_truncated_or_fake_gzip() {
    let dir = scratch("bad_gzip");
    let path = dir.join("ticks.csv.gz");
    let mut s = sample();
    s.events.truncate(6);
    for i in 0..2000u64 {
        s.events.push(Event::Tick {
            t_ns: u64::MAX - 1000 + i / 2,
            encoder: 1,
            step: 1,
        });
    }
    s.events.sort_by_key(Event::t_ns);
    tickstream::write(&path, &s).unwrap();
    let bytes = fs::read(&path).unwrap();
    fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let e = tickstream::read(&path).unwrap_err();
    assert!(e.line.is_some_and(|l| l > 3), "{e}");
    assert!(e.message.contains("read error"), "{e}");

    let fake = dir.join("plain.csv.gz");
    fs::write(&fake, stream_text(&[])).unwrap();
    let e = tickstream::read(&fake).unwrap_err();
    assert!(e.message.contains("not gzip-compressed"), "{e}");

    // gzip data under a plain name but passed past the sniffing (as the second line).
    let mut text = format!("{MAGIC}\n").into_bytes();
    text.extend_from_slice(&bytes[..40]);
    let e = read_bytes_err(&text);
    assert!(e.line == Some(2), "{e}");
}

#[test]
fn error_overlong_line() {
    let mut text = stream_text(&[]);
    text.push_str(&"1".repeat(tickstream::MAX_LINE_BYTES + 10));
    let e = read_err(&text);
    assert_err(&e, Some(3), "longer than");
}

// ---- robustness --------------------------------------------------------------------------

/// A small linear congruential generator (Knuth's MMIX constants): no extra dependencies.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn never_panics_on_garbage() {
    let mut rng = Lcg(2024);
    let valid = fs::read(data("python-crlf.csv")).unwrap();
    let alphabet = b"0123456789+-.,#\"\r\n \teEtickabsruhNnaIf\xff\xc3";
    let mut results = [0usize; 2];
    for case in 0..600 {
        let bytes: Vec<u8> = match case % 3 {
            // Random bytes, after the magic line half of the time.
            0 => {
                let mut b = if rng.below(2) == 0 {
                    format!("{MAGIC}\n{HEADER}\n").into_bytes()
                } else {
                    Vec::new()
                };
                let n = rng.below(300);
                b.extend((0..n).map(|_| rng.next() as u8));
                b
            }
            // Random text from an alphabet the parser cares about.
            1 => {
                let mut b = format!("{MAGIC}\n{HEADER}\n").into_bytes();
                let n = rng.below(300);
                b.extend((0..n).map(|_| alphabet[rng.below(alphabet.len())]));
                b
            }
            // A valid file with a few bytes changed, inserted or removed.
            _ => {
                let mut b = valid.clone();
                for _ in 0..1 + rng.below(4) {
                    let i = rng.below(b.len());
                    match rng.below(3) {
                        0 => b[i] = alphabet[rng.below(alphabet.len())],
                        1 => b.insert(i, rng.next() as u8),
                        _ => {
                            b.remove(i);
                        }
                    }
                }
                b
            }
        };
        match tickstream::read_from(&bytes[..], Path::new("garbage.csv")) {
            Ok(s) => {
                results[0] += 1;
                assert!(s.events.windows(2).all(|w| w[0].t_ns() <= w[1].t_ns()));
            }
            Err(e) => {
                results[1] += 1;
                assert!(!e.message.is_empty());
                // Every error on a line names a line that exists.
                let lines = bytes.split(|&b| b == b'\n').count() as u64;
                assert!(e.line.is_none_or(|l| l >= 1 && l <= lines), "{e}");
            }
        }
    }
    // Both outcomes happen, so the generator exercises the parser.
    assert!(results[0] > 20 && results[1] > 200, "{results:?}");
}

#[test]
fn never_panics_on_garbage_files_named_gz() {
    let dir = scratch("garbage_gz");
    let mut rng = Lcg(7);
    let mut good = Vec::new();
    {
        let mut e = flate2::write::GzEncoder::new(&mut good, flate2::Compression::default());
        e.write_all(&fs::read(data("python-crlf.csv")).unwrap())
            .unwrap();
        e.finish().unwrap();
    }
    for case in 0..200 {
        let mut b = good.clone();
        let i = 2 + rng.below(b.len() - 2);
        b[i] ^= 1 << rng.below(8);
        if case % 4 == 0 {
            b.truncate(rng.below(b.len()));
        }
        let path = dir.join("g.csv.gz");
        fs::write(&path, &b).unwrap();
        let _ = tickstream::read(&path);
    }
}

/// A stream of nothing but comments (a small gzip of them expands to gigabytes) keeps a
/// bounded amount of them, and says how many it dropped.
#[test]
fn comments_are_kept_up_to_a_bound_and_the_rest_counted() {
    let mut text = String::from("# omnibench tick stream v1\n");
    let line = format!("# {}\n", "c".repeat(98));
    for _ in 0..20_000 {
        text.push_str(&line); // 2 MB of comments
    }
    text.push_str("t_ns,kind,id,value,x_m,y_m,theta_rad\n0,truth,,,0,0,0\n");
    let s = read_ok(&text);
    let kept: usize = s.comments.iter().map(String::len).sum();
    assert!(kept <= tickstream::MAX_KEPT_COMMENT_BYTES + 200, "{kept}");
    let last = s.comments.last().unwrap();
    let dropped = 20_000 - (s.comments.len() - 1);
    assert!(
        last.starts_with(&format!("({dropped} more comment lines not kept")),
        "{last}"
    );
    assert_eq!(s.events.len(), 1);
}
