//! Which track point each rig landmark is read from, and which mesh vertex it sits on:
//! the iBUG-68 path, the dense MediaPipe 468 path and any `landmark,vertex` CSV.
//!
//! A track layout is known by its point count: 68 (iBUG / Multi-PIE), 468 (MediaPipe Face
//! Mesh) or 478 (MediaPipe Face Landmarker: the 468 and two irises). A correspondence names,
//! for some of the layout's points, the vertex of the rig's mesh that point is; points it
//! does not name are left out of the solve (the rig does not cover them).

use keyshape_core::error::{Error, Result};
use std::path::Path;

/// The built-in dense MediaPipe Face Mesh → ICT FaceKit correspondence: 462 of the 468
/// points, each the nearest ICT vertex after a similarity and a thin-plate warp through the
/// 68 sparse pairs (`tools/make_mediapipe468_to_ict.py`; the six left out are the face
/// oval's points beside the ears, where the ICT face has no front).
const MEDIAPIPE468_TO_ICT: &str = include_str!("../../../assets/features/mediapipe468_to_ict.csv");

/// The track layouts a rig reads, by point count.
pub const LAYOUTS: [usize; 4] = [68, 70, 468, 478];

/// iBUG 68 with the pupils (`Layout::ibug70`): what OpenSeeFace's datagrams become.
pub const IBUG_PUPILS: usize = 70;

/// The MediaPipe Face Landmarker's iris centres (subject's right, then left): the rig
/// landmarks that make eye gaze visible.
pub const IRIS_CENTRES: [usize; 2] = [468, 473];

/// Is the layout iBUG-numbered (68 points, or 70 with the pupils), so its first 68 points
/// are the iBUG ones and no MediaPipe map applies?
pub fn is_ibug(layout: usize) -> bool {
    layout == 68 || layout == IBUG_PUPILS
}

/// A layout's pupils or iris centres (subject's right, then left) — MediaPipe 468 and 473,
/// iBUG-with-pupils 68 and 69 — or None for a layout without them.
pub fn pupils(layout: usize) -> Option<[usize; 2]> {
    match layout {
        478 => Some(IRIS_CENTRES),
        IBUG_PUPILS => Some([68, 69]),
        _ => None,
    }
}

/// The outer eye corners of a layout (subject's right, then left) — iBUG 36 and 45,
/// MediaPipe 33 and 263 — or None for a point count that is not a layout.
pub fn eye_corners(layout: usize) -> Option<[usize; 2]> {
    match layout {
        68 | IBUG_PUPILS => Some([36, 45]),
        468 | 478 => Some([33, 263]),
        _ => None,
    }
}

/// Refuses a point count that is no layout a rig reads.
pub fn check_layout(points: usize) -> Result<()> {
    if LAYOUTS.contains(&points) {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "a rig reads 68-point tracks in iBUG order, iBUG with the pupils (70: what OpenSeeFace sends), MediaPipe Face Mesh tracks (468 points) or Face Landmarker tracks (478: the 468 and two irises); this one has {points} points"
        )))
    }
}

/// Reads a `landmark,vertex` CSV of any length: each row names a track point (`landmark`,
/// the tracker's own numbering) and the mesh vertex it sits on. A landmark may be named once;
/// every vertex must be below `vertices`; at least four landmarks (the head pose needs
/// them). Rows keep the file's order.
pub fn read_correspondence(path: &Path, vertices: usize) -> Result<Vec<(usize, usize)>> {
    let text = keyshape_io::read_text(path)?;
    parse_correspondence(path, &text, vertices)
}

fn parse_correspondence(path: &Path, text: &str, vertices: usize) -> Result<Vec<(usize, usize)>> {
    let mut rdr = csv::Reader::from_reader(text.as_bytes());
    let mut lines = keyshape_io::csv_error::LineCounter::new(text.as_bytes());
    let mut out: Vec<(usize, usize)> = Vec::new();
    let mut seen = std::collections::HashMap::new();
    for r in rdr.records() {
        let r = r.map_err(|e| keyshape_io::csv_error::csv_error_in(path, &e, text.as_bytes()))?;
        let line = r.position().map_or(0, |p| lines.line_at(p.byte()));
        let field = |c: usize| -> Result<usize> {
            let v = r.get(c).unwrap_or("").trim();
            v.parse::<usize>()
                .map_err(|_| Error::parse(path, line, c as u64 + 1, format!("not an index: '{v}'")))
        };
        let (l, v) = (field(0)?, field(1)?);
        if v >= vertices {
            return Err(Error::parse(
                path,
                line,
                2,
                format!("landmark {l} names vertex {v}, but the mesh has {vertices} vertices"),
            ));
        }
        if let Some(first) = seen.insert(l, line) {
            return Err(Error::parse(
                path,
                line,
                1,
                format!("landmark {l} is named twice (first on line {first})"),
            ));
        }
        out.push((l, v));
    }
    if out.len() < 4 {
        return Err(Error::file(
            path,
            format!(
                "names {} landmark(s); the head pose needs at least 4",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// Reads a `landmark,vertex` CSV naming a vertex for each of the 68 iBUG landmarks exactly
/// once (a rig folder's `landmarks_multipie68.csv`), in landmark order.
pub fn read_landmark_vertices(path: &Path, vertices: usize) -> Result<Vec<usize>> {
    let pairs = read_correspondence(path, vertices)?;
    let mut out = vec![None; 68];
    for &(l, v) in &pairs {
        match out.get_mut(l) {
            Some(o) => *o = Some(v),
            None => {
                return Err(Error::file(
                    path,
                    format!("landmark {l} is not one of the 68 (0–67)"),
                ))
            }
        }
    }
    let missing: Vec<String> = (0..68)
        .filter(|&l| out[l].is_none())
        .map(|l| l.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(Error::file(
            path,
            format!("no vertex for landmark(s) {}", missing.join(", ")),
        ));
    }
    Ok(out.into_iter().flatten().collect())
}

/// The built-in dense MediaPipe 468 → ICT FaceKit correspondence (track point, ICT vertex).
pub fn mediapipe468_to_ict() -> Result<Vec<(usize, usize)>> {
    let pairs = parse_correspondence(
        Path::new("assets/features/mediapipe468_to_ict.csv"),
        MEDIAPIPE468_TO_ICT,
        usize::MAX,
    )?;
    if pairs.iter().any(|&(l, _)| l >= 468) {
        return Err(Error::invalid(
            "built-in 468 → ICT correspondence is malformed",
        ));
    }
    Ok(pairs)
}

/// The ICT FaceKit face's vertex count and its iBUG-30 (nose tip) vertex: how a rig folder
/// is known to be the ICT face the built-in dense correspondence was derived on.
const ICT_VERTICES: usize = 9409;
const ICT_NOSE_TIP: usize = 4857;

/// A rig read for a track layout: the mesh and morph targets (for exports) and the rig.
pub type RigParts = (
    keyshape_io::obj::Mesh,
    keyshape_io::morph::MorphTargets,
    super::Rig,
);

/// Reads the rig at `path` — a folder in the ICT FaceKit layout or a glTF/GLB with morph
/// targets — for a track of `layout` points (68, 468 or 478). The landmarks:
/// - `csv`, a `landmark,vertex` correspondence of any length, when given (required for a
///   glTF rig);
/// - else, for 68 points, the folder's `landmarks_multipie68.csv`; for 70 (iBUG and pupils,
///   OpenSeeFace's) the same without the outer mouth corners OpenSeeFace does not track;
/// - else, for MediaPipe points, the folder's `landmarks_mediapipe468.csv` if it has one,
///   or the built-in dense correspondence if the folder is the ICT face it was derived on.
///
/// With 478 or 70 points and a folder whose mesh has no eyeballs, the iris centres are added as
/// [`add_virtual_irises`] places them (unless `csv` names them).
pub fn read_rig(path: &Path, layout: usize, csv: Option<&Path>) -> Result<RigParts> {
    check_layout(layout)?;
    if !path.exists() {
        return Err(Error::file(
            path,
            "no such folder or file (a rig folder like ../shared/data/ict_facekit_face, or a .glb/.gltf with a landmark,vertex CSV)",
        ));
    }
    // A rig folder is an input whole: no output may replace any file of it.
    keyshape_io::atomic::register_input(path)?;
    let (mesh, morph, pairs) = if path.is_dir() {
        let (mesh, morph, marks) = super::Rig::read_ict_parts(path)?;
        let n = mesh.positions.len();
        let pairs = match (csv, layout) {
            (Some(c), _) => read_correspondence(c, n)?,
            (None, 68) => marks.iter().copied().enumerate().collect(),
            // OpenSeeFace does not track the outer mouth corners: they are left out.
            (None, IBUG_PUPILS) => marks
                .iter()
                .copied()
                .enumerate()
                .filter(|(l, _)| {
                    !keyshape_core::sequence::OPENSEEFACE_UNTRACKED
                        .iter()
                        .any(|u| u.0 == *l)
                })
                .collect(),
            (None, _) => {
                let own = path.join("landmarks_mediapipe468.csv");
                if own.exists() {
                    read_correspondence(&own, n)?
                } else if n == ICT_VERTICES && marks.get(30) == Some(&ICT_NOSE_TIP) {
                    mediapipe468_to_ict()?
                } else {
                    return Err(Error::file(
                        path,
                        "a MediaPipe track needs this rig's landmarks_mediapipe468.csv (landmark,vertex for the MediaPipe points it covers): the built-in dense correspondence is for the ICT FaceKit face",
                    ));
                }
            }
        };
        (mesh, morph, pairs)
    } else {
        let Some(c) = csv else {
            return Err(Error::file(
                path,
                "a glTF rig needs a landmark,vertex CSV naming the mesh vertex of each track point it covers",
            ));
        };
        let (mesh, morph) = super::gltf_rig::read_gltf_mesh(path)?;
        let pairs = read_correspondence(c, mesh.positions.len())?;
        (mesh, morph, pairs)
    };
    if let Some(c) = csv {
        check_against_track(&pairs, layout, &c.display().to_string())?;
    }
    let mut rig = super::Rig::from_correspondence(&mesh.positions, &morph, layout, &pairs)?;
    if pupils(layout).is_some() && path.is_dir() && !rig.sees_pupils() {
        let travel = read_gaze_travel(&path.join("expressions.csv"))?;
        add_virtual_irises(&mut rig, &travel)?;
    }
    Ok((mesh, morph, rig))
}

/// The sparser rig a quick neutral search reads ([`super::preview_frame`]) for a MediaPipe
/// track: the rig folder's own 68-landmark map (`landmarks_multipie68.csv`) on the mesh and
/// morph targets already read (`parts`). `None` for a 68-point track (the rig is that
/// sparse already) and for a glTF rig (no 68-point map of its own).
pub fn search_rig(path: &Path, layout: usize, parts: &RigParts) -> Result<Option<super::Rig>> {
    if layout == 68 || layout == IBUG_PUPILS || !path.is_dir() {
        return Ok(None);
    }
    let (mesh, morph, _) = parts;
    let marks =
        read_landmark_vertices(&path.join("landmarks_multipie68.csv"), mesh.positions.len())?;
    super::Rig::from_parts(&mesh.positions, morph, &marks).map(Some)
}

/// A rig as the user names it — a folder in the ICT layout or a glTF/GLB, with an optional
/// `landmark,vertex` CSV — read for whichever track layout comes (the lab keeps one and
/// solves every track it opens onto it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RigSource {
    /// The folder or glTF file.
    pub path: std::path::PathBuf,
    /// The correspondence CSV, overriding the rig's own (required for glTF).
    pub landmarks: Option<std::path::PathBuf>,
}

impl RigSource {
    /// The rig at `path`, with its own landmarks.
    pub fn new(path: impl Into<std::path::PathBuf>) -> RigSource {
        RigSource {
            path: path.into(),
            landmarks: None,
        }
    }

    /// [`read_rig`] for a track of `layout` points.
    pub fn read_for(&self, layout: usize) -> Result<RigParts> {
        read_rig(&self.path, layout, self.landmarks.as_deref())
    }
}

impl super::Rig {
    /// The track layout's polylines through the rig's landmarks (indices into
    /// [`super::Rig::neutral`]; a correspondence need not list its points in order).
    pub fn polylines(&self) -> Vec<Vec<usize>> {
        let Some(layout) = keyshape_core::sequence::Layout::for_points(self.layout) else {
            return Vec::new();
        };
        let mut order: Vec<usize> = (0..self.points.len()).collect();
        order.sort_by_key(|&i| self.points[i]);
        let sorted: Vec<usize> = order.iter().map(|&i| self.points[i]).collect();
        keyshape_core::sequence::polylines_for(&layout, &sorted)
            .into_iter()
            .map(|l| l.into_iter().map(|i| order[i]).collect())
            .collect()
    }
}

/// Refuses a correspondence that names a point past the track's `points`.
pub fn check_against_track(pairs: &[(usize, usize)], points: usize, what: &str) -> Result<()> {
    check_layout(points)?;
    if let Some(&(l, _)) = pairs.iter().find(|&&(l, _)| l >= points) {
        return Err(Error::invalid(format!(
            "{what} names landmark {l}, but the track has {points} points (0–{})",
            points - 1
        )));
    }
    Ok(())
}

/// How far the ICT face's eyeballs travel per gaze shape, read from a rig folder's
/// `expressions.csv` (`max_abs_offset_outside_cm`: the largest offset of the parts the
/// folder dropped, eyeballs among them — for a gaze shape, the front of the eyeball).
pub fn read_gaze_travel(path: &Path) -> Result<Vec<(String, f64)>> {
    let text = keyshape_io::read_text(path)?;
    let mut rdr = csv::Reader::from_reader(text.as_bytes());
    let header = rdr
        .headers()
        .map_err(|e| keyshape_io::csv_error::csv_error_in(path, &e, text.as_bytes()))?
        .clone();
    let col = |n: &str| header.iter().position(|h| h.trim() == n);
    let (Some(name), Some(off)) = (col("shape"), col("max_abs_offset_outside_cm")) else {
        return Err(Error::file(
            path,
            "has no shape and max_abs_offset_outside_cm columns: the iris points cannot be placed",
        ));
    };
    let mut lines = keyshape_io::csv_error::LineCounter::new(text.as_bytes());
    let mut out = Vec::new();
    for r in rdr.records() {
        let r = r.map_err(|e| keyshape_io::csv_error::csv_error_in(path, &e, text.as_bytes()))?;
        let line = r.position().map_or(0, |p| lines.line_at(p.byte()));
        let shape = r.get(name).unwrap_or("").trim();
        if !super::is_gaze(shape) {
            continue;
        }
        let v = r.get(off).unwrap_or("").trim();
        let cm: f64 = v
            .parse()
            .ok()
            .filter(|c: &f64| c.is_finite() && *c >= 0.0)
            .ok_or_else(|| {
                Error::parse(
                    path,
                    line,
                    off as u64 + 1,
                    format!("not a distance in cm: '{v}'"),
                )
            })?;
        out.push((shape.to_string(), cm));
    }
    Ok(out)
}

/// Adds the two iris centres of a 478-point track (MediaPipe 468 and 473), or the pupils of
/// a 70-point one (68 and 69: OpenSeeFace's), to a rig whose mesh has no eyeballs, as
/// landmarks of their own: each sits at the centroid of its eye's landmarks (the layout's
/// `right_eye` / `left_eye` groups), and a gaze shape moves it by
/// `travel` (cm at weight 1, see [`read_gaze_travel`]) in the direction the shape names —
/// eyeLookOut/In along x (out is away from the nose), Up/Down along y. Other shapes leave it
/// still. A model: the eyeball turns about its centre, and at the angles a gaze shape
/// reaches its front moves nearly in the image plane.
pub fn add_virtual_irises(rig: &mut super::Rig, travel: &[(String, f64)]) -> Result<()> {
    let (Some([right, left]), Some(layout)) = (
        pupils(rig.layout),
        keyshape_core::sequence::Layout::for_points(rig.layout),
    ) else {
        return Err(Error::invalid(format!(
            "iris points are read from 478-point tracks and pupils from 70-point ones (iBUG and pupils); this rig reads {} points",
            rig.layout
        )));
    };
    for (centre, group, side) in [(right, "right_eye", "_R"), (left, "left_eye", "_L")] {
        if rig.points.contains(&centre) {
            continue;
        }
        let members: Vec<usize> = layout
            .groups
            .get(group)
            .map_or(&[][..], |g| g.points.as_slice())
            .iter()
            .filter_map(|p| rig.points.iter().position(|q| q == p))
            .collect();
        if members.len() < 3 {
            return Err(Error::unfit(format!(
                "the rig reads {} points of the track's {group}: too few to place its iris",
                members.len()
            )));
        }
        let mut at = [0.0; 3];
        for &m in &members {
            for a in 0..3 {
                at[a] += rig.neutral[m][a] / members.len() as f64;
            }
        }
        // +x is the subject's left: "out" of the left eye is +x, of the right eye −x.
        let out_sign = if side == "_L" { 1.0 } else { -1.0 };
        rig.neutral.push(at);
        rig.points.push(centre);
        for (s, d) in rig.deltas.iter_mut().enumerate() {
            let name = &rig.names[s];
            let step = travel.iter().find(|(n, _)| n == name).map_or(0.0, |t| t.1);
            let dir = match name.strip_suffix(side) {
                Some("eyeLookOut") => [out_sign, 0.0],
                Some("eyeLookIn") => [-out_sign, 0.0],
                Some("eyeLookUp") => [0.0, 1.0],
                Some("eyeLookDown") => [0.0, -1.0],
                _ => [0.0, 0.0],
            };
            d.push([step * dir[0], step * dir[1], 0.0]);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_built_in_dense_correspondence_names_distinct_vertices() {
        let p = mediapipe468_to_ict().unwrap();
        assert_eq!(p.len(), 462);
        let mut v: Vec<usize> = p.iter().map(|x| x.1).collect();
        v.sort_unstable();
        v.dedup();
        assert_eq!(v.len(), 462);
        // Nose tip: MediaPipe 1 is ICT's iBUG-30 vertex.
        assert!(p.contains(&(1, 4857)));
    }

    #[test]
    fn a_csv_of_any_length_is_read_and_bad_rows_are_placed() {
        let p = Path::new("m.csv");
        let ok = parse_correspondence(p, "landmark,vertex\n5,1\n9,2\n1,3\n2,0\n", 4).unwrap();
        assert_eq!(ok, vec![(5, 1), (9, 2), (1, 3), (2, 0)]);
        let e = parse_correspondence(p, "landmark,vertex\n5,1\n9,7\n", 4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.csv:3:2") && e.contains("vertex 7"), "{e}");
        let e = parse_correspondence(p, "landmark,vertex\n5,1\n5,2\n", 4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.csv:3:1") && e.contains("named twice"), "{e}");
        let e = parse_correspondence(p, "landmark,vertex\n5,1\n6,x\n", 4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.csv:3:2: not an index: 'x'"), "{e}");
        let e = parse_correspondence(p, "landmark,vertex\n5,1\n", 4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 4"), "{e}");
        let e = check_against_track(&ok, 7, "m.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("7 points"), "{e}");
        let e = check_against_track(&[(470, 0)], 468, "m.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("landmark 470") && e.contains("468 points"),
            "{e}"
        );
    }
}
