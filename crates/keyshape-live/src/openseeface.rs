//! OpenSeeFace's tracking datagrams (its `facetracker.py` sends one per video frame to UDP
//! port 11573): one or more faces of [`FACE_BYTES`] bytes each, little-endian.
//!
//! | bytes | field |
//! |---|---|
//! | 8 | f64 time (seconds) |
//! | 4 | i32 face id |
//! | 4 + 4 | f32 width, height (the camera image, px) |
//! | 4 + 4 | f32 right, left eye open |
//! | 1 | u8 3-D fit succeeded |
//! | 4 | f32 fit error |
//! | 16 | quaternion (4 f32) |
//! | 12 | Euler angles (3 f32) |
//! | 12 | translation (3 f32) |
//! | 68 × 4 | f32 confidence per landmark |
//! | 68 × 8 | landmark (f32 x, f32 y) in image pixels, x to the right, y down |
//! | 70 × 12 | 3-D points (3 f32) |
//! | 14 × 4 | f32 features (eye, eyebrow and mouth measures) |
//!
//! The tracker holds each landmark as (row, column) and writes the column first, so each
//! image point arrives as (x, y) with x the column — as OpenSee.cs reads it.

/// Landmarks per face (iBUG 68).
pub const POINTS: usize = 68;
/// Bytes of one face.
pub const FACE_BYTES: usize =
    8 + 4 + 4 + 4 + 4 + 4 + 1 + 4 + 16 + 12 + 12 + 68 * 4 + 68 * 8 + 70 * 12 + 14 * 4;

/// One face of a datagram (the fields the solve uses; the 3-D points and features are read
/// past).
#[derive(Debug, Clone, PartialEq)]
pub struct Face {
    /// The tracker's time stamp (seconds).
    pub time: f64,
    /// The face's id (several faces: `--face ID` follows one).
    pub id: i32,
    /// The camera image's width and height (px).
    pub size: [f32; 2],
    /// Right and left eye openness.
    pub eye_open: [f32; 2],
    /// Did the tracker's own 3-D fit succeed?
    pub success: bool,
    /// Per landmark, the tracker's confidence.
    pub confidence: Vec<f32>,
    /// The 68 landmarks, x then y each, image pixels (y down).
    pub points: Vec<f64>,
}

/// Why a datagram was skipped.
#[derive(Debug, Clone, PartialEq)]
pub enum Malformed {
    /// Empty, or a length that is no whole number of faces.
    Size(usize),
    /// A landmark or the time is not a finite number.
    NotFinite {
        /// The face's position in the datagram.
        face: usize,
        /// What was not finite.
        what: String,
    },
}

impl std::fmt::Display for Malformed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Malformed::Size(n) => write!(
                f,
                "{n} bytes is not a whole number of OpenSeeFace faces ({FACE_BYTES} bytes each)"
            ),
            Malformed::NotFinite { face, what } => {
                write!(f, "face {face}: {what} is not a finite number")
            }
        }
    }
}

/// Little-endian reads from a face's bytes.
struct Le<'a> {
    b: &'a [u8],
    at: usize,
}

impl Le<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(s) = self.b.get(self.at..self.at + N) {
            out.copy_from_slice(s);
        }
        self.at += N;
        out
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
}

/// Decodes a datagram into its faces.
pub fn decode(datagram: &[u8]) -> Result<Vec<Face>, Malformed> {
    if datagram.is_empty() || datagram.len() % FACE_BYTES != 0 {
        return Err(Malformed::Size(datagram.len()));
    }
    datagram
        .chunks_exact(FACE_BYTES)
        .enumerate()
        .map(|(k, b)| decode_face(k, b))
        .collect()
}

fn decode_face(k: usize, b: &[u8]) -> Result<Face, Malformed> {
    let mut r = Le { b, at: 0 };
    let time = f64::from_le_bytes(r.take());
    let id = i32::from_le_bytes(r.take());
    let size = [r.f32(), r.f32()];
    let eye_open = [r.f32(), r.f32()];
    let success = r.take::<1>()[0] != 0;
    // Fit error, quaternion, Euler angles, translation: not used.
    r.at += 4 + 16 + 12 + 12;
    let confidence: Vec<f32> = (0..POINTS).map(|_| r.f32()).collect();
    let points: Vec<f64> = (0..2 * POINTS).map(|_| f64::from(r.f32())).collect();
    if !time.is_finite() {
        return Err(Malformed::NotFinite {
            face: k,
            what: "the time".into(),
        });
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(Malformed::NotFinite {
            face: k,
            what: format!("landmark {}", i / 2),
        });
    }
    Ok(Face {
        time,
        id,
        size,
        eye_open,
        success,
        confidence,
        points,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_face_is_1785_bytes_as_openseeface_writes_it() {
        assert_eq!(super::FACE_BYTES, 1785);
    }
}
