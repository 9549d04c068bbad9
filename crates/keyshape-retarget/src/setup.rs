//! The glue a retargeting run needs around [`super::retarget`]: drawing contours for a point
//! selection and the built-in target for a sequence.

use super::target::{cartoon_warp, iod};
use keyshape_core::decompose::{prepare, PrepareOptions, Prepared};
use keyshape_core::error::{setting, Error, Result};
use keyshape_core::rbf::Rbf;
use keyshape_core::sequence::Sequence;

pub use keyshape_core::sequence::{named_polylines_for, polylines_for};

/// The built-in cartoon target for `seq` and the mean inter-ocular distance: the warp is
/// fitted on the mean of the whole face aligned exactly as `prep` was, so it maps `prep`'s
/// (selected) aligned points.
pub fn builtin_target(seq: &Sequence, prep: &Prepared) -> Result<(Rbf, f64)> {
    if seq.dims != 2 {
        return Err(Error::bad_setting(
            "dims",
            seq.dims,
            format!(
                "the built-in target is 2-D: use {} 2, or give {}",
                setting("dims"),
                setting("target")
            ),
        ));
    }
    let layout = prep.layout.as_ref().ok_or_else(|| {
        Error::invalid(format!(
            "the built-in target needs a known layout (468 or 68 points), not {}",
            seq.points
        ))
    })?;
    // Alignment always fits the whole face and then keeps the selected points, so when
    // every point is kept `prep` already is the whole prepared face: no second copy.
    let all_points = prep.point_indices.len() == seq.points
        && prep.point_indices.iter().enumerate().all(|(i, &p)| i == p);
    let mean = if all_points {
        prep.seq.coords.column_mean()
    } else {
        prepare(
            seq,
            &PrepareOptions {
                points: None,
                align: prep.head.is_some(),
            },
        )?
        .seq
        .coords
        .column_mean()
    };
    Ok((
        cartoon_warp(mean.as_slice(), layout)?,
        iod(mean.as_slice(), layout)?,
    ))
}
