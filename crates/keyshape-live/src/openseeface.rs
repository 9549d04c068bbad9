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
//!
//! The 68 points are OpenSeeFace's own, not iBUG 68: its landmark model's 66 points (iBUG
//! without the outer mouth corners) and the two pupils of its gaze model. [`Face::ibug70`]
//! puts them where [`Layout::ibug70`](keyshape_core::sequence::Layout::ibug70) has them,
//! the layout the rig reads them in (checked against captures of the real tracker in the
//! crate's tests).

use keyshape_core::sequence::{OPENSEEFACE_TO_IBUG70, OPENSEEFACE_UNTRACKED};

/// Points per face in a datagram (OpenSeeFace's 66 and its two pupils).
pub const POINTS: usize = 68;

/// Points per frame once put in iBUG order with the pupils ([`Face::ibug70`]).
pub const IBUG70_POINTS: usize = 70;

/// A pupil OpenSeeFace itself does not draw (`facetracker.py`'s visualisation): its
/// confidence below this, or its eye less open than [`PUPIL_MIN_OPEN`]. With
/// `--gaze-tracking 0` it sends both pupils as (0, 0) with confidence 0.
pub const PUPIL_MIN_CONFIDENCE: f32 = 0.2;
/// See [`PUPIL_MIN_CONFIDENCE`].
pub const PUPIL_MIN_OPEN: f32 = 0.3;
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
    /// The 68 points in OpenSeeFace's order, x then y each, image pixels (y down).
    pub points: Vec<f64>,
}

impl Face {
    /// The face's points in iBUG order with the pupils (70 points, x then y each), and the
    /// pupils that were not tracked (subject's right, then left). iBUG 48 and 54, which
    /// OpenSeeFace does not track, repeat its mouth corners (iBUG 60 and 64) so the frame
    /// draws as a face; a rig leaves them out. A pupil OpenSeeFace would not draw itself
    /// ([`PUPIL_MIN_CONFIDENCE`]: no gaze tracking, or an eye nearly closed) is put at the
    /// centre of its eye's six points — looking ahead — rather than at the (0, 0) the
    /// tracker sends.
    pub fn ibug70(&self) -> (Vec<f64>, [bool; 2]) {
        let mut out = vec![0.0; 2 * IBUG70_POINTS];
        for (i, &to) in OPENSEEFACE_TO_IBUG70.iter().enumerate() {
            out[2 * to] = self.points[2 * i];
            out[2 * to + 1] = self.points[2 * i + 1];
        }
        for (missing, from) in OPENSEEFACE_UNTRACKED {
            out[2 * missing] = out[2 * from];
            out[2 * missing + 1] = out[2 * from + 1];
        }
        let mut untracked = [false; 2];
        // Pupils: 66 (right) and 67 (left); eye openness right, then left; the eyes'
        // six points iBUG 36–41 (right) and 42–47 (left).
        for side in 0..2 {
            let conf = self.confidence.get(66 + side).copied().unwrap_or(0.0);
            if conf >= PUPIL_MIN_CONFIDENCE && self.eye_open[side] >= PUPIL_MIN_OPEN {
                continue;
            }
            untracked[side] = true;
            let eye = 36 + 6 * side;
            for a in 0..2 {
                out[2 * (68 + side) + a] =
                    (eye..eye + 6).map(|p| out[2 * p + a]).sum::<f64>() / 6.0;
            }
        }
        (out, untracked)
    }
}

impl Face {
    /// The tracker's confidence in each of [`Face::ibug70`]'s points: OpenSeeFace's own,
    /// put in iBUG order; iBUG 48 and 54 take their stand-ins' (60, 64); a pupil
    /// [`Face::ibug70`] put at its eye's centre has 0 (not seen: the solve leaves it out).
    pub fn confidence70(&self) -> Vec<f64> {
        let mut out = vec![0.0; IBUG70_POINTS];
        for (i, &to) in OPENSEEFACE_TO_IBUG70.iter().enumerate() {
            out[to] = f64::from(self.confidence.get(i).copied().unwrap_or(0.0));
        }
        for (missing, from) in OPENSEEFACE_UNTRACKED {
            out[missing] = out[from];
        }
        let (_, untracked) = self.ibug70();
        for (side, &u) in untracked.iter().enumerate() {
            if u {
                out[68 + side] = 0.0;
            }
        }
        out
    }
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

/// The records of a capture of what the tracker sent (`.osfcap`, as
/// `../shared/data/openseeface_captures` holds them): per datagram, the f64 arrival time
/// (Unix seconds), a u32 length and the datagram, little-endian. `None` when the bytes end
/// inside a record.
pub fn capture_records(bytes: &[u8]) -> Option<Vec<(f64, &[u8])>> {
    let mut out = Vec::new();
    let mut at = 0usize;
    while at < bytes.len() {
        let head = bytes.get(at..at + 12)?;
        let time = f64::from_le_bytes(head[..8].try_into().ok()?);
        let len = u32::from_le_bytes(head[8..].try_into().ok()?) as usize;
        out.push((time, bytes.get(at + 12..at + 12 + len)?));
        at += 12 + len;
    }
    Some(out)
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

    #[test]
    fn a_capture_cut_inside_a_record_is_refused() {
        let mut b = Vec::new();
        for (t, d) in [(1.5f64, &b"abc"[..]), (2.5, &b""[..])] {
            b.extend(t.to_le_bytes());
            b.extend((d.len() as u32).to_le_bytes());
            b.extend(d);
        }
        let r = super::capture_records(&b).unwrap();
        assert_eq!(r, [(1.5, &b"abc"[..]), (2.5, &b""[..])]);
        for cut in [1, 12, 14, b.len() - 1] {
            assert_eq!(super::capture_records(&b[..cut]), None, "cut at {cut}");
        }
        assert_eq!(super::capture_records(&[]), Some(Vec::new()));
    }
}
