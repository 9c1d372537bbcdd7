//! The field splitter and the error-message field display.

use super::row::{shown, split_fields};
use super::*;

fn split(text: &str) -> Result<Vec<&str>, String> {
    let mut fields = Vec::new();
    split_fields(text, &mut fields)?;
    Ok(fields.iter().map(|&(a, b)| &text[a..b]).collect())
}

#[test]
fn splits_plain_and_quoted_fields() {
    assert_eq!(split("").unwrap(), vec![""]);
    assert_eq!(split("a,,b,").unwrap(), vec!["a", "", "b", ""]);
    assert_eq!(
        split(r#""0","tick" ,"a,""b""",x"#).unwrap(),
        vec!["0", "tick", r#"a,""b"""#, "x"]
    );
    assert_eq!(split(r#""""#).unwrap(), vec![""]);
    assert!(split(r#"1,"abc"#).unwrap_err().contains("unterminated"));
    assert!(split(r#""a"b,1"#)
        .unwrap_err()
        .contains("after the closing quote"));
}

#[test]
fn shown_cuts_long_fields_at_a_char_boundary() {
    let long = "é".repeat(100);
    let s = shown(&long);
    assert!(s.ends_with("..."), "{s}");
    assert_eq!(s.chars().filter(|&c| c == 'é').count(), 40);
    assert_eq!(shown("2"), "2");
    assert_eq!(shown("a b"), "\"a b\"");
    assert_eq!(
        shown("x".repeat(50).as_str()),
        format!("{}...", "x".repeat(40))
    );
}

#[test]
fn magic_prefix_is_magic_without_its_version() {
    assert_eq!(format!("{MAGIC_PREFIX}1"), MAGIC);
}
