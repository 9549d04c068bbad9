//! Landmark layouts: named groups of feature points with polylines for drawing.
//!
//! Three layouts are built in: MediaPipe Face Mesh 468 (index lists embedded from
//! `assets/layout_mediapipe468.json`, derived from mediapipe 0.10.14's
//! `face_mesh_connections.py`, Apache-2.0 — see `assets/NOTICE`), MediaPipe Face
//! Landmarker 478 (the 468 and two irises of five points) and iBUG 68.

use crate::error::{Error, Result};
use serde::Deserialize;
use std::collections::BTreeMap;

const MEDIAPIPE_JSON: &str = include_str!("../../../../assets/layout_mediapipe468.json");

const MEDIAPIPE_TO_IBUG: &str =
    include_str!("../../../../assets/features/mediapipe468_to_ibug68.json");

/// For each iBUG-68 landmark, the MediaPipe Face Mesh landmark read in its place: derived by
/// `tools/make_mediapipe_to_ibug68.py` from MediaPipe's canonical face aligned to the ICT
/// neutral (see the file's description; a geometric derivation, not a published table).
pub fn mediapipe_to_ibug68() -> Result<Vec<usize>> {
    #[derive(serde::Deserialize)]
    struct File {
        mediapipe: Vec<usize>,
    }
    let f: File = serde_json::from_str(MEDIAPIPE_TO_IBUG)
        .map_err(|e| Error::invalid(format!("built-in 468 → 68 correspondence: {e}")))?;
    if f.mediapipe.len() != 68 || f.mediapipe.iter().any(|&i| i >= 468) {
        return Err(Error::invalid(
            "built-in 468 → 68 correspondence is malformed",
        ));
    }
    Ok(f.mediapipe)
}

/// For each of OpenSeeFace's 68 points, the point of [`Layout::ibug70`] it is (checked
/// against the tracker's own 3-D face model, `face_3d` in its `tracker.py`): its 66-point
/// landmark model is iBUG 68 without the outer mouth corners 48 and 54 — 0–47 as iBUG,
/// 48–52 the upper outer lip (iBUG 49–53), 53–57 the lower (55–59), 58–65 the inner lip
/// from the subject's right corner (60–67) — and 66, 67 are the right and left pupils.
pub const OPENSEEFACE_TO_IBUG70: [usize; 68] = {
    let mut m = [0usize; 68];
    let mut i = 0;
    while i < 68 {
        m[i] = match i {
            0..=47 => i,
            48..=52 => i + 1,
            _ => i + 2,
        };
        i += 1;
    }
    m
};

/// The iBUG points OpenSeeFace does not track (the outer mouth corners): a track made from
/// its datagrams repeats the inner corners there, and a rig leaves them out.
pub const OPENSEEFACE_UNTRACKED: [(usize, usize); 2] = [(48, 60), (54, 64)];

/// One named group of feature points.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Group {
    /// Point indices, ascending.
    pub points: Vec<usize>,
    /// Ordered polylines for drawing; a closed loop repeats its first index.
    #[serde(default)]
    pub polylines: Vec<Vec<usize>>,
}

/// A named set of groups over a fixed number of points.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Layout {
    /// Layout name, e.g. `mediapipe_face_mesh_468` or `ibug68`.
    pub name: String,
    /// Number of points the layout indexes.
    pub points: usize,
    /// Groups by name.
    pub groups: BTreeMap<String, Group>,
    /// The layout this one extends (name, points), whose points are this one's first ones:
    /// regions, eye corners and correspondences made for it serve this one too.
    #[serde(skip)]
    pub extends: Option<(String, usize)>,
}

/// Group names that stand for several groups, on any layout that has the parts.
const ALIASES: [(&str, &[&str]); 5] = [
    ("irises", &["left_iris", "right_iris"]),
    ("eyes", &["left_eye", "right_eye"]),
    ("brows", &["left_eyebrow", "right_eyebrow"]),
    ("eyebrows", &["left_eyebrow", "right_eyebrow"]),
    ("mouth", &["lips"]),
];

impl Layout {
    /// The MediaPipe Face Mesh 468-point layout.
    pub fn mediapipe468() -> Layout {
        // The embedded file is checked by a unit test; a failure here is a build defect.
        match serde_json::from_str::<Layout>(MEDIAPIPE_JSON) {
            Ok(l) => l,
            Err(_) => Layout {
                name: "mediapipe_face_mesh_468".into(),
                points: 468,
                groups: BTreeMap::new(),
                extends: None,
            },
        }
    }

    /// MediaPipe Face Landmarker's 478 points (its default output): the Face Mesh 468 and
    /// ten iris points, each iris a centre and four points around it — `right_iris`
    /// 468–472 (centre 468), `left_iris` 473–477 (centre 473), left and right as the
    /// subject's, as the eye groups are (`FACEMESH_LEFT_IRIS` = 474–477 in mediapipe's
    /// `face_mesh_connections.py`).
    pub fn mediapipe478() -> Layout {
        let mut l = Layout::mediapipe468();
        l.extends = Some((l.name.clone(), l.points));
        l.name = "mediapipe_face_landmarker_478".into();
        l.points = 478;
        for (name, centre) in [("right_iris", 468usize), ("left_iris", 473)] {
            let ring: Vec<usize> = (centre + 1..centre + 5).chain([centre + 1]).collect();
            l.groups.insert(
                name.into(),
                Group {
                    points: (centre..centre + 5).collect(),
                    polylines: vec![ring],
                },
            );
        }
        l
    }

    /// The name of the layout this one extends, or its own: what regions, eye corners and
    /// feature correspondences are keyed by.
    pub fn family(&self) -> &str {
        self.extends.as_ref().map_or(&self.name, |(n, _)| n)
    }

    /// The point count of [`Layout::family`].
    pub fn family_points(&self) -> usize {
        self.extends.as_ref().map_or(self.points, |(_, p)| *p)
    }

    /// The iBUG / Multi-PIE 68-point layout (0-based): jaw 0–16, brows 17–21 and 22–26
    /// (subject's right, then left), nose 27–35, eyes 36–41 and 42–47, lips 48–67.
    pub fn ibug68() -> Layout {
        let run = |a: usize, b: usize| (a..=b).collect::<Vec<_>>();
        let closed = |a: usize, b: usize| {
            let mut v = run(a, b);
            v.push(a);
            v
        };
        let mut groups = BTreeMap::new();
        let mut add = |name: &str, points: Vec<usize>, polylines: Vec<Vec<usize>>| {
            groups.insert(name.to_string(), Group { points, polylines });
        };
        add("jaw", run(0, 16), vec![run(0, 16)]);
        add("right_eyebrow", run(17, 21), vec![run(17, 21)]);
        add("left_eyebrow", run(22, 26), vec![run(22, 26)]);
        add("nose", run(27, 35), vec![run(27, 30), run(31, 35)]);
        add("right_eye", run(36, 41), vec![closed(36, 41)]);
        add("left_eye", run(42, 47), vec![closed(42, 47)]);
        add("lips", run(48, 67), vec![closed(48, 59), closed(60, 67)]);
        Layout {
            name: "ibug68".into(),
            points: 68,
            groups,
            extends: None,
        }
    }

    /// iBUG 68 with the two pupils (70 points): the 68 in iBUG order, then the subject's
    /// right pupil (68, group `right_iris`) and left pupil (69, `left_iris`). What
    /// OpenSeeFace's datagrams become ([`OPENSEEFACE_TO_IBUG70`]): its own 66-point
    /// landmark model has no outer mouth corners (iBUG 48 and 54 repeat its corners, 60 and
    /// 64, so the face draws whole) and its gaze model adds the pupils.
    pub fn ibug70() -> Layout {
        let mut l = Layout::ibug68();
        l.extends = Some((l.name.clone(), l.points));
        l.name = "ibug68_pupils".into();
        l.points = 70;
        for (name, p) in [("right_iris", 68usize), ("left_iris", 69)] {
            l.groups.insert(
                name.into(),
                Group {
                    points: vec![p],
                    polylines: Vec::new(),
                },
            );
        }
        l
    }

    /// The built-in layout for a point count (468 → MediaPipe Face Mesh, 478 → MediaPipe
    /// Face Landmarker with irises, 68 → iBUG, 70 → iBUG and pupils), if any.
    pub fn for_points(points: usize) -> Option<Layout> {
        match points {
            468 => Some(Layout::mediapipe468()),
            478 => Some(Layout::mediapipe478()),
            68 => Some(Layout::ibug68()),
            70 => Some(Layout::ibug70()),
            _ => None,
        }
    }

    /// Every group and alias name this layout answers to.
    pub fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.groups.keys().cloned().collect();
        for (alias, parts) in ALIASES {
            if parts.iter().all(|p| self.groups.contains_key(*p)) {
                names.push(alias.to_string());
            }
        }
        names
    }

    /// Point indices (sorted, unique) of a comma-separated selection such as `lips` or
    /// `eyes,brows`. `all` selects every point.
    pub fn select(&self, spec: &str) -> Result<Vec<usize>> {
        let mut out = Vec::new();
        for name in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if name == "all" {
                out.extend(0..self.points);
                continue;
            }
            let parts: Vec<&str> = match ALIASES.iter().find(|(a, _)| *a == name) {
                Some((_, parts)) => parts.to_vec(),
                None => vec![name],
            };
            for part in parts {
                let group = self.groups.get(part).ok_or_else(|| {
                    Error::bad_setting(
                        "points",
                        name,
                        format!(
                            "unknown point group '{name}' for layout {} (known: {}, all)",
                            self.name,
                            self.names().join(", ")
                        ),
                    )
                })?;
                out.extend(group.points.iter().copied());
            }
        }
        out.sort_unstable();
        out.dedup();
        if out.is_empty() {
            return Err(Error::bad_setting(
                "points",
                spec,
                format!("point selection '{spec}' is empty"),
            ));
        }
        if let Some(&bad) = out.iter().find(|&&p| p >= self.points) {
            return Err(Error::invalid(format!(
                "layout {} names point {bad}, but it has {} points",
                self.name, self.points
            )));
        }
        Ok(out)
    }
}

/// The layout's polylines restricted to the selected points, renumbered to selection
/// indices (a polyline is cut where it leaves the selection).
pub fn polylines_for(layout: &Layout, selected: &[usize]) -> Vec<Vec<usize>> {
    named_polylines_for(layout, selected)
        .into_iter()
        .map(|(_, l)| l)
        .collect()
}

/// [`polylines_for`] with the name of the layout group each polyline comes from.
pub fn named_polylines_for(layout: &Layout, selected: &[usize]) -> Vec<(String, Vec<usize>)> {
    let pos = |p: usize| selected.binary_search(&p).ok();
    let mut out = Vec::new();
    for (name, g) in &layout.groups {
        for line in &g.polylines {
            let mut run = Vec::new();
            for &p in line {
                match pos(p) {
                    Some(i) => run.push(i),
                    None => {
                        if run.len() > 1 {
                            out.push((name.clone(), std::mem::take(&mut run)));
                        }
                        run.clear();
                    }
                }
            }
            if run.len() > 1 {
                out.push((name.clone(), run));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_mediapipe_layout_parses_with_all_groups() {
        let l: Layout = serde_json::from_str(MEDIAPIPE_JSON).unwrap();
        assert_eq!(l.points, 468);
        for g in [
            "face_oval",
            "lips",
            "left_eye",
            "right_eye",
            "left_eyebrow",
            "right_eyebrow",
            "nose",
        ] {
            let grp = &l.groups[g];
            assert!(!grp.points.is_empty() && grp.points.iter().all(|&p| p < 468));
            assert!(!grp.polylines.is_empty());
        }
        assert_eq!(l, Layout::mediapipe468());
    }

    /// OpenSeeFace's points land on distinct iBUG points in order, skipping only the two
    /// outer mouth corners, with the pupils last; the layout extends iBUG 68.
    #[test]
    fn openseeface_points_are_ibug_without_the_outer_corners_and_two_pupils() {
        let m = OPENSEEFACE_TO_IBUG70;
        assert!(m.windows(2).all(|w| w[0] < w[1]));
        let missing: Vec<usize> = (0..70).filter(|p| !m.contains(p)).collect();
        assert_eq!(missing, [48, 54]);
        assert_eq!(
            OPENSEEFACE_UNTRACKED.map(|(p, _)| p).to_vec(),
            missing,
            "the untracked points are the ones no OpenSeeFace point lands on"
        );
        // Its mouth corners (58, 62) are iBUG's inner corners, its pupils 68 and 69.
        assert_eq!([m[58], m[62], m[66], m[67]], [60, 64, 68, 69]);
        let l = Layout::for_points(70).unwrap();
        assert_eq!((l.family(), l.family_points()), ("ibug68", 68));
        assert_eq!(l.select("irises").unwrap(), [68, 69]);
        assert_eq!(l.select("lips").unwrap(), (48..68).collect::<Vec<_>>());
    }

    #[test]
    fn the_landmarker_layout_is_the_face_mesh_and_two_irises() {
        let m = Layout::mediapipe468();
        let l = Layout::for_points(478).unwrap();
        assert_eq!(
            (l.points, l.family(), l.family_points()),
            (478, m.name.as_str(), 468)
        );
        assert_eq!(m.family(), m.name);
        for (name, g) in &m.groups {
            assert_eq!(l.groups.get(name), Some(g), "{name}");
        }
        assert_eq!(
            l.select("right_iris").unwrap(),
            (468..473).collect::<Vec<_>>()
        );
        assert_eq!(
            l.select("left_iris").unwrap(),
            (473..478).collect::<Vec<_>>()
        );
        assert_eq!(l.select("irises").unwrap(), (468..478).collect::<Vec<_>>());
        // Each ring is closed around its centre, which it leaves out.
        assert_eq!(
            l.groups["left_iris"].polylines,
            vec![vec![474, 475, 476, 477, 474]]
        );
        assert_eq!(l.select("all").unwrap().len(), 478);
        assert!(m.select("irises").is_err());
    }

    #[test]
    fn ibug_groups_cover_all_68_points_once() {
        let l = Layout::ibug68();
        let mut all: Vec<usize> = l.groups.values().flat_map(|g| g.points.clone()).collect();
        all.sort_unstable();
        assert_eq!(all, (0..68).collect::<Vec<_>>());
    }

    #[test]
    fn aliases_expand_and_unknown_groups_name_the_choices() {
        let l = Layout::ibug68();
        assert_eq!(l.select("eyes").unwrap(), (36..48).collect::<Vec<_>>());
        assert_eq!(l.select("mouth").unwrap(), l.select("lips").unwrap());
        let e = l.select("lipz").unwrap_err().to_string();
        assert!(e.contains("lipz") && e.contains("lips"), "{e}");
    }
}
