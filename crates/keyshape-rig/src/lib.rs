//! A tracked performance solved onto a blendshape rig: the rig's 68 landmark
//! vertices under a per-frame scaled orthographic camera, fitted jointly with the shape
//! weights, warm-started from the previous frame, with the person's identity taken from a
//! neutral frame and the shapes a 2-D track cannot see frozen.
//!
//! eos's `fit_blendshapes_to_landmarks_nnls` alternates a camera fit and an NNLS solve. On
//! the 55-shape ICT rig that alternation crawls (the camera and the shapes trade motion), so
//! each step here is a Gauss–Newton step of camera and weights together, the camera's six
//! parameters eliminated by their Schur complement, backtracked with the weights solved
//! exactly (under their bounds) for each trial camera: the error never rises, and on
//! noise-free renders it converges to the rendered weights (tested to 1e-6).
//!
//! The rig is [`model`] (read from ICT FaceKit or a glTF), solved as [`options`] say, giving
//! an [`outcome`]; the steps are in `solve` (the whole track), `frame` (one frame), `prior`,
//! `neutral`, `identifiability` and [`temporal`].

pub mod accuracy;
pub mod camera;
mod checks;
pub mod correspondence;
mod depth;
mod frame;
pub mod gltf_rig;
mod identifiability;
pub mod live;
pub mod livelink;
pub mod model;
mod neutral;
pub mod options;
pub mod outcome;
pub mod plausibility;
pub mod preview;
mod prior;
pub mod refine;
mod solve;
pub mod temporal;

pub use depth::DEPTH_PRIOR;
use frame::{frame_depth, frame_points, FrameSolver};
pub use identifiability::{identifiability, identifiability_weighted};
pub use model::{Rig, LANDMARKS};
pub use neutral::{
    NeutralRule, NeutralView, NEUTRAL_CANDIDATES, NEUTRAL_LIPS_WARN, NEUTRAL_SCORED_FRAMES,
    NEUTRAL_TURN_WARN_DEG, OWN_FACE_ACTIVITY,
};
pub use options::{
    landmark_weights, Identity, Neutral, RigOptions, SmoothUnit, LANDMARK_GROUPS, LIVE_PRIOR,
    LIVE_SMOOTH, RECOMMENDED_PRIOR, RECOMMENDED_ZERO_PHASE, ROBUST_C, TAPER_STEPS, TAPER_TOLERANCE,
};
pub use outcome::{largest_weights, RigSolve, ShapeReport};
pub use preview::{preview_frame, FramePreview, PREVIEW_SCORED_FRAMES};
pub use prior::{is_gaze, track_iod, EXCLUSIVE, GAZE_DAMPING};
pub use solve::{solve_rig, solve_rig_observed, zero_phase};

pub use correspondence::{read_correspondence, read_landmark_vertices};
pub use keyshape_core::sequence::mediapipe_to_ibug68;
