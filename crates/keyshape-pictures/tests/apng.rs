//! The APNG writer: one frame per frame asked for, read back by the png crate's decoder.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[test]
fn apng_has_one_frame_per_sequence_frame() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.png");
    keyshape_pictures::render::apng::write_apng(&p, 3, 30.0, &|i| {
        let mut pm = tiny_skia::Pixmap::new(8, 8).unwrap();
        pm.fill(tiny_skia::Color::from_rgba8(i as u8 * 80, 0, 0, 255));
        Ok(pm)
    })
    .unwrap();
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()));
    let reader = dec.read_info().unwrap();
    let actl = reader.info().animation_control().unwrap();
    assert_eq!(actl.num_frames, 3);
}
