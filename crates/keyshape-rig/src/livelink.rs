//! Live Link Face CSV (Epic's iOS app's recording format): `Timecode,BlendshapeCount,`
//! then 61 values per frame in the app's own order — the 52 ARKit shapes, HeadYaw,
//! HeadPitch, HeadRoll and the two eyes' yaw, pitch and roll. Its packets (and Unreal's
//! `EARFaceBlendShape`) order the shapes as [`COLUMNS`]; its CSV swaps two pairs
//! ([`CSV_ORDER`]: JawRight before JawLeft, MouthRight before MouthLeft), as a real
//! capture's header row shows.

use super::Rig;
use std::io::Write;

/// The 61 value columns, in Live Link Face's order.
pub const COLUMNS: [&str; 61] = [
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawLeft",
    "JawRight",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthLeft",
    "MouthRight",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
];

/// The CSV's columns as indices into [`COLUMNS`]: the packet order with JawLeft/JawRight
/// and MouthLeft/MouthRight swapped, as the app writes its CSV.
pub const CSV_ORDER: [usize; 61] = {
    let mut o = [0usize; 61];
    let mut i = 0;
    while i < 61 {
        o[i] = match i {
            15 => 16,
            16 => 15,
            21 => 22,
            22 => 21,
            _ => i,
        };
        i += 1;
    }
    o
};

/// The ARKit name of a rig shape name: ICT's `mouthSmile_L` → `MouthSmileLeft`, `jawOpen` →
/// `JawOpen`; ARKit names (`mouthSmileLeft`, `MouthSmileLeft`) map to themselves.
pub fn arkit_name(rig_name: &str) -> String {
    let (stem, side) = match rig_name.rsplit_once('_') {
        Some((s, "L")) | Some((s, "l")) => (s, "Left"),
        Some((s, "R")) | Some((s, "r")) => (s, "Right"),
        _ => (rig_name, ""),
    };
    let mut c = stem.chars();
    let head: String = c
        .next()
        .map(|h| h.to_uppercase().collect())
        .unwrap_or_default();
    format!("{head}{}{side}", c.as_str())
}

/// For each of the 52 ARKit columns, the rig shapes averaged into it: one shape usually;
/// both halves where the rig splits a shape ARKit keeps whole (ICT's `browInnerUp_L/_R`,
/// `cheekPuff_L/_R`); none where the rig lacks it (written as 0). Rig shapes ARKit lacks
/// (ICT's `cheekRaiser_L/_R`) are in no column.
pub fn column_sources(rig: &Rig) -> Vec<Vec<usize>> {
    let names: Vec<String> = rig.names.iter().map(|n| arkit_name(n)).collect();
    COLUMNS[..52]
        .iter()
        .map(|col| {
            let exact: Vec<usize> = (0..names.len()).filter(|&i| names[i] == *col).collect();
            if !exact.is_empty() {
                return exact;
            }
            (0..names.len())
                .filter(|&i| names[i] == format!("{col}Left") || names[i] == format!("{col}Right"))
                .collect()
        })
        .collect()
}

/// One frame's 61 values in [`COLUMNS`] order: each ARKit column the mean of its rig
/// shapes (`sources`, from [`column_sources`]; 0 where it has none) in `w` (rig order),
/// then the head's yaw, pitch and roll (radians), then the six eye angles (not solved: 0).
pub fn frame_values(sources: &[Vec<usize>], w: &[f64], head: [f64; 3]) -> [f64; 61] {
    let mut out = [0.0; 61];
    for (o, src) in out.iter_mut().zip(sources) {
        if !src.is_empty() {
            *o = src.iter().map(|&s| w[s]).sum::<f64>() / src.len() as f64;
        }
    }
    out[52..55].copy_from_slice(&head);
    out
}

/// `HH:MM:SS:FF.mmm` for time `t` seconds at `fps` frames per second (Live Link Face's
/// timecode: frame within the second, then the fraction of a frame in thousandths).
pub fn timecode(t: f64, fps: f64) -> String {
    let t = t.max(0.0);
    let whole = t.floor();
    let secs = whole as u64;
    let frames = (t - whole) * fps;
    let ff = frames.floor();
    let milli = ((frames - ff) * 1000.0).round().min(999.0) as u64;
    format!(
        "{:02}:{:02}:{:02}:{:02}.{milli:03}",
        // A timecode is a time of day: its hours wrap at 24.
        (secs / 3600) % 24,
        (secs / 60) % 60,
        secs % 60,
        ff as u64
    )
}

/// One frame's row of the CSV: its timecode, the value count and the 61 values (in
/// [`CSV_ORDER`]).
pub fn record(
    sources: &[Vec<usize>],
    w: &[f64],
    head: [f64; 3],
    t: f64,
    fps: f64,
    count: &str,
) -> Vec<String> {
    let v = frame_values(sources, w, head);
    [timecode(t, fps), count.to_string()]
        .into_iter()
        .chain(CSV_ORDER.iter().map(|&c| keyshape_io::fmt_num(v[c])))
        .collect()
}

/// The CSV's header, as a real capture's: `Timecode`, `BlendshapeCount` and the 61
/// columns in [`CSV_ORDER`].
pub fn header() -> impl Iterator<Item = &'static str> {
    ["Timecode", "BlendshapeCount"]
        .into_iter()
        .chain(CSV_ORDER.iter().map(|&c| COLUMNS[c]))
}

/// Writes the CSV (its header [`header`], rows [`record`]): per frame, its time (seconds), the rig weights (rig order) and the head's
/// yaw, pitch and roll (radians).
pub fn write(
    out: &mut dyn Write,
    rig: &Rig,
    times: &[f64],
    fps: f64,
    weights: &nalgebra::DMatrix<f64>,
    head: &[[f64; 3]],
) -> std::io::Result<()> {
    let sources = column_sources(rig);
    let count = COLUMNS.len().to_string();
    let header = header();
    let records = times.iter().enumerate().map(|(f, &t)| {
        let w: Vec<f64> = weights.column(f).iter().copied().collect();
        record(&sources, &w, head[f], t, fps, &count)
    });
    keyshape_io::csv_out::write_records(out, header, records)
}
