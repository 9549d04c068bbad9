//! The heat map of a matrix (the orthogonality table's picture).

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

/// The orthogonality picture: the cells carry their value's colour, names label the columns
/// as well as the rows (the picture is taller than the grid and its scale by the longest
/// name), and the colour scale runs from white to the colour of 1.
#[test]
fn orthogonality_picture_has_both_axes_and_a_scale() {
    let names: Vec<String> = ["a", "a_much_longer_name", "c"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let mut m = nalgebra::DMatrix::identity(3, 3);
    m[(0, 2)] = 1.0;
    m[(0, 1)] = 0.0;
    let cell = 40u32;
    let pm = keyshape_pictures::render::heat::heat_maps(&[("t", &m)], &names, cell).unwrap();
    let longest = keyshape_pictures::render::text::width("a_much_longer_name", 11.0) as u32;
    assert!(
        pm.height() >= 40 + longest + 3 * cell + 20 + 56,
        "{}",
        pm.height()
    );
    let colours: std::collections::HashSet<[u8; 3]> = pm
        .pixels()
        .iter()
        .map(|p| [p.red(), p.green(), p.blue()])
        .collect();
    assert!(
        colours.contains(&[150, 10, 10]),
        "the cell of 1 and the scale's end"
    );
    assert!(colours.contains(&[255, 255, 255]));
    // Ink above the grid: the column names.
    let grid_top = 40 + longest + 10;
    let ink_above = (45..grid_top - 2).any(|y| {
        (130..130 + 3 * cell).any(|x| {
            let p = pm.pixel(x, y).unwrap();
            p.red() < 120 && p.green() < 120
        })
    });
    assert!(ink_above, "column names drawn above the grid");
}
