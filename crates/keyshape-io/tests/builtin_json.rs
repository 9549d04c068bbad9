//! The tables built into the binary by layout family (both crates' regions go through
//! `builtin_json`): the family's table parsed, and the two ways it fails named.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_io::builtin_json;

#[derive(serde::Deserialize, Debug, PartialEq)]
struct Table {
    k: usize,
}

const TABLES: [(&str, &str); 2] = [("ibug68", r#"{"k": 68}"#), ("broken", r#"{"k": "#)];

#[test]
fn the_familys_own_table_is_parsed() {
    let t: Table = builtin_json("tables", "ibug68", &TABLES).unwrap();
    assert_eq!(t, Table { k: 68 });
}

#[test]
fn a_family_without_a_table_and_a_table_that_does_not_parse_are_named() {
    let e = builtin_json::<Table>("tables", "mediapipe_face_mesh_468", &TABLES).unwrap_err();
    assert_eq!(
        e.to_string(),
        "no built-in tables for layout mediapipe_face_mesh_468"
    );
    let e = builtin_json::<Table>("tables", "broken", &TABLES).unwrap_err();
    assert!(e.to_string().starts_with("built-in tables: "), "{e}");
}
