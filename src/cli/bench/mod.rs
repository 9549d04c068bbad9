//! `kslab bench`: the measurements behind BENCHMARKS.md, each in one run so ratios compare
//! like with like.

mod curves;
mod kmeans;
mod live;
mod nnls;
mod rig;
mod scale;
mod smooth;
mod transfer;
mod tui;

use anyhow::Result;
use clap::{Args, Subcommand};

/// Arguments of `kslab bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, Subcommand)]
enum What {
    /// Batch NNLS throughput against a textbook solver and the normal equations.
    Nnls(nnls::NnlsArgs),
    /// The full error-curve sweep (all methods, k = 2..24) against a plain implementation.
    Curves(curves::CurvesBenchArgs),
    /// k-means seeding: the lab's (greedy k-means++, 3 restarts) against linfa's default.
    Kmeans(kmeans::KmeansBenchArgs),
    /// Paper 004 mesh deformation throughput on the ICT face.
    Transfer(transfer::TransferBenchArgs),
    /// The offline temporal prior against the unsmoothed batch NNLS, and its memory.
    Smooth(smooth::SmoothBenchArgs),
    /// `kslab live` fed in real time on loopback: latency from arrival to sending, drops, CPU.
    Live(live::LiveBenchArgs),
    /// Rig solve throughput (camera + 55 ICT shapes per frame) on one core.
    Rig(rig::RigBenchArgs),
    /// Wall time and peak memory of solve, keys and curves on long generated tracks.
    Scale(scale::ScaleArgs),
    /// Input-to-redraw latency of the lab when k or the method changes.
    Tui(tui::TuiBenchArgs),
}

pub fn run(a: &BenchArgs) -> Result<()> {
    match &a.what {
        What::Nnls(n) => nnls::run(n),
        What::Curves(c) => curves::run(c),
        What::Kmeans(k) => kmeans::run(k),
        What::Tui(t) => tui::run(t),
        What::Transfer(t) => transfer::run(t),
        What::Smooth(s) => smooth::run(s),
        What::Rig(r) => rig::run(r),
        What::Live(l) => live::run(l),
        What::Scale(s) => scale::run(s),
    }
}
