//! Retargeting (paper 000 §4.1 Eq. 2 and §5): the weights solved on the source key shapes
//! drive target key shapes, `B_t = Σ wᵢ Bᵢ` (absolute) or `N_B + Σ wᵢ (Bᵢ − N_B)` (delta),
//! optionally per face region with linear blending, and the head motion removed by
//! alignment is put back.

//!
//! The modules: [`apply`] (the key plan, the target and the solve), [`result`] (what it
//! gives), [`head`] (head motion put back), [`regions`], [`setup`] (the built-in target),
//! [`svg`] (templates an artist redraws) and [`target`] (target key shapes read from files).

pub mod apply;
pub mod head;
pub mod regions;
pub mod result;
pub mod setup;
pub mod svg;
pub mod target;

pub use apply::{retarget, retarget_errors, KeyPlan, RetargetParams, Target};
pub use head::{with_head_motion, with_relative_head_motion};
pub use result::{jitter, Retargeted};
