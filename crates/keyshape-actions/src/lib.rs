//! Paper 002 (Cosker, Borkett, Marshall, Rosin, *Towards automatic performance driven
//! animation between multiple types of facial model*), on landmark shapes: the shape half of
//! the paper's appearance models (we have tracked points, not images, so there is no
//! texture).
//!
//! * [`actions`]: one example frame per action, chosen from the track;
//! * [`modes`]: region-based artificial training sets, action-specific modes and the
//!   orthogonality measure of Table 2 (§3.1, §5 Eq. 9);
//! * [`trajectory`]: action-mode trajectories, their normalisation and the mapping between
//!   two people's models (§3.2);
//! * [`morph`]: morph targets driven by action tracks (§3.3, Eq. 8);
//! * [`intensity`]: soft-KNN action intensities, median-3 and polynomial smoothing and the
//!   correlation of Eq. 10 (§4, §5.1).

pub mod actions;
pub mod intensity;
pub mod modes;
pub mod morph;
pub mod regions;
pub mod trajectory;
