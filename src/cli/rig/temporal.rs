//! The priors in time and magnitude from the command line, shared by `kslab rig`,
//! `rig-accuracy` and `live`.

use anyhow::Result;
use keyshape_core::solve::temporal::SmoothMode;
use keyshape_rig::SmoothUnit;

/// The temporal prior's λ and its unit from `--smooth` (`kslab rig`, `rig-accuracy`,
/// `live`): a λ given is in pixels; the live path's default is relative to the face
/// ([`keyshape_rig::LIVE_SMOOTH`] × IOD²), an offline solve's is none.
pub(crate) fn smooth_of(live: bool, given: Option<f64>) -> (f64, SmoothUnit) {
    match (live, given) {
        (_, Some(l)) => (l, SmoothUnit::Pixels),
        (true, None) => (keyshape_rig::LIVE_SMOOTH, SmoothUnit::Iod),
        (false, None) => (0.0, SmoothUnit::Pixels),
    }
}

/// The priors in time and magnitude that `kslab rig` and `rig-accuracy` share, from their
/// flags (`--live`, `--zero-phase`, `--smooth`, `--smooth-mode`, `--prior`,
/// `--no-prior-taper`), with the defaults of each path and the same refusals: what
/// reads frames still to come under `--live`, a mode or a taper with nothing to apply to.
pub(crate) struct Temporal {
    pub(crate) zero_phase: f64,
    pub(crate) smooth: f64,
    pub(crate) smooth_unit: SmoothUnit,
    pub(crate) smooth_mode: SmoothMode,
    pub(crate) prior: f64,
}

impl Temporal {
    pub(crate) fn of(
        live: bool,
        (zero_phase, smooth, smooth_mode): (Option<f64>, Option<f64>, Option<&str>),
        prior: Option<f64>,
        no_prior_taper: bool,
    ) -> Result<Temporal> {
        let zero_phase = match (live, zero_phase) {
            (true, Some(z)) if z != 0.0 => anyhow::bail!(
                "--live is causal: --zero-phase {z} smooths with frames still to come; drop one of them"
            ),
            (true, _) => 0.0,
            (false, z) => z.unwrap_or(keyshape_rig::RECOMMENDED_ZERO_PHASE),
        };
        let mode = match (live, smooth_mode) {
            (true, Some("offline")) => anyhow::bail!(
                "--live is causal: --smooth-mode offline solves each clip with frames still to come; drop one of them"
            ),
            (true, _) | (false, Some("causal")) => SmoothMode::Causal,
            (false, _) => SmoothMode::Offline,
        };
        let (lambda, smooth_unit) = smooth_of(live, smooth);
        if smooth_mode.is_some() && lambda == 0.0 {
            anyhow::bail!("--smooth-mode applies to the temporal prior: give --smooth λ > 0");
        }
        let prior = prior.unwrap_or(if live {
            keyshape_rig::LIVE_PRIOR
        } else {
            keyshape_rig::RECOMMENDED_PRIOR
        });
        if no_prior_taper && prior == 0.0 {
            anyhow::bail!("--no-prior-taper: there is no prior to taper (--prior 0)");
        }
        Ok(Temporal {
            zero_phase,
            smooth: lambda,
            smooth_unit,
            smooth_mode: mode,
            prior,
        })
    }
}
