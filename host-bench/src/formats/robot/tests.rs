//! The loader's own tests: where errors are located, and the checks the fixtures in
//! `tests/data/robots/` do not reach.

use std::path::Path;

use super::*;
use crate::formats::toml_file::{key_on_line, line_col, table_header};

fn parse(text: &str) -> Result<Robot, RobotError> {
    Robot::parse(text, Path::new("t.toml"))
}

const HEAD: &str = "format = \"omnibench robot v1\"\nname = \"t\"\n";

#[test]
fn line_col_counts_characters_from_one() {
    let t = "ab\nγδ = 1\n";
    assert_eq!(line_col(t, 0), (1, 1));
    assert_eq!(line_col(t, 3), (2, 1));
    assert_eq!(line_col(t, 3 + "γδ ".len()), (2, 4));
    assert_eq!(line_col(t, 1000), (3, 1));
}

#[test]
fn key_on_line_follows_headers() {
    let t = "a = 1\n[[e]]\nx = 1\n[[e]]\nx = \"\n[c]\ny = 2\n";
    let at = |line: usize| {
        let off: usize = t.lines().take(line - 1).map(|l| l.len() + 1).sum();
        key_on_line(t, off)
    };
    assert_eq!(at(1).as_deref(), Some("a"));
    assert_eq!(at(4).as_deref(), Some("e[1]"));
    assert_eq!(at(5).as_deref(), Some("e[1].x"));
    assert_eq!(at(7).as_deref(), Some("c.y"));
}

#[test]
fn table_headers_are_told_from_arrays() {
    assert_eq!(
        table_header("[[encoders]]"),
        Some(("encoders".into(), true))
    );
    assert_eq!(
        table_header("[carriage] # x"),
        Some(("carriage".into(), false))
    );
    assert_eq!(table_header("[1, 2],"), None);
}

#[test]
fn syntax_errors_name_key_and_line() {
    let e = parse(&format!("{HEAD}[[encoders]]\nname = \"a\nx_m = 1\n")).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(4), Some("encoders[0].name")),
        "{e}"
    );
    let e = parse(&format!("{HEAD}[carriage]\ntrail_m = 0.1\ntrail_m = 0.2\n")).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(5), Some("carriage.trail_m")),
        "{e}"
    );
}

#[test]
fn inline_tables_are_located_too() {
    let e = parse(&format!(
        "{HEAD}drive_wheels = [\n  {{ x_m = 0, y_m = 0, direction_deg = 0, v_max_m_s = 1 }},\n  {{ x_m = 0, y_m = true, direction_deg = 0, v_max_m_s = 1 }},\n]\n"
    ))
    .unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(5), Some("drive_wheels[1].y_m")),
        "{e}"
    );
    assert!(e.message.contains("expected a number"), "{e}");
}

#[test]
fn missing_keys_are_named() {
    let e = parse("format = \"omnibench robot v1\"\n").unwrap_err();
    assert_eq!((e.line, e.key.as_deref()), (Some(1), Some("name")), "{e}");
    let e = parse(&format!("{HEAD}[[encoders]]\nname = \"a\"\ny_m = 0\n")).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(3), Some("encoders[0].x_m")),
        "{e}"
    );
}

#[test]
fn other_format_versions_are_refused_first() {
    let e = parse("format = \"omnibench robot v2\"\nname = \"t\"\nnew_key = 1\n").unwrap_err();
    assert_eq!((e.line, e.key.as_deref()), (Some(1), Some("format")), "{e}");
    assert!(e.message.contains("unsupported"), "{e}");
}

#[test]
fn table_shapes_are_checked() {
    let e = parse(&format!("{HEAD}[[carriage]]\ntrail_m = 0.06\n")).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(3), Some("carriage")),
        "{e}"
    );
    assert!(e.message.contains("at most one carriage"), "{e}");
    let e = parse(&format!("{HEAD}[encoders]\nname = \"a\"\n")).unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(3), Some("encoders")),
        "{e}"
    );
}

#[test]
fn non_finite_values_are_refused() {
    let e = parse(&format!(
        "{HEAD}[[drive_wheels]]\nx_m = nan\ny_m = 0\ndirection_deg = 0\nv_max_m_s = 1\n"
    ))
    .unwrap_err();
    assert_eq!(
        (e.line, e.key.as_deref()),
        (Some(4), Some("drive_wheels[0].x_m")),
        "{e}"
    );
}

#[test]
fn absolute_encoder_levels_round_trip() {
    let a = AbsoluteEncoder {
        name: "s".into(),
        bits: 8,
        gray: true,
        inverted: true,
        measures: AbsMeasures::CarriageSwivel,
    };
    for p in 0..256u16 {
        assert_eq!(a.decode(a.levels(p)), p);
    }
    // Inverted Gray: position 1 is Gray 0b1, shown as all pins high but bit 0.
    assert_eq!(a.levels(1), 0xFE);
    assert_eq!(a.decode(0xFF), 0);
}

#[test]
fn display_has_path_line_column_key() {
    let e = parse(&format!(
        "{HEAD}[[encoders]]\nname = \"a\"\nx_m = 0\ny_m = 0\ndirection_deg = 0\nmetres_per_count = -1\n"
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.toml:8:20: key `encoders[0].metres_per_count`: a count must be 1e-7 to 0.0625 m of wheel \
         travel, got -1 m"
    );
}
