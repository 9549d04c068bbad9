//! `kslab live`'s closing summary on the terminal, and `--stats`.

use super::LiveArgs;
use anyhow::Result;
use keyshape_live::session::Session;
use keyshape_live::Counters;
use std::io::IsTerminal;

/// The closing summary, and --stats.
pub(super) fn report(
    a: &LiveArgs,
    (name, rig): (&str, &keyshape_rig::Rig),
    session: &Session,
    counters: &Counters,
    seconds: f64,
) -> Result<()> {
    let (received, malformed, dropped) = counters.get();
    let untracked = counters
        .untracked
        .load(std::sync::atomic::Ordering::Relaxed);
    let others = counters
        .other_faces
        .load(std::sync::atomic::Ordering::Relaxed);
    let lat = |q| session.latencies().quantile(q);
    errln!(
        "{}kslab live: {} frames solved in {seconds:.1} s ({received} received, {dropped} dropped, {malformed} malformed, {untracked} untracked, {others} of other faces, {} refused, {} not sent{}); latency p50 {} p99 {}",
        if std::io::stderr().is_terminal() { "\r\x1b[K" } else { "" },
        session.solved(),
        session.refused(),
        session.send_errors(),
        match session.sinks_behind() {
            0 => String::new(),
            n => format!(", {n} missed by a sink that fell behind"),
        },
        ms(lat(0.5)),
        ms(lat(0.99)),
    );
    if let Some(p) = &a.stats {
        let v = serde_json::json!({
            "source": name,
            "landmarks": rig.landmarks(),
            "shapes": rig.k(),
            "seconds": seconds,
            "solved": session.solved(),
            "received": received,
            "dropped": dropped,
            "malformed": malformed,
            "untracked": untracked,
            "other_faces": others,
            "refused": session.refused(),
            "not_sent": session.send_errors(),
            "sinks_behind": session.sinks_behind(),
            "latency_ms": { "p50": lat(0.5), "p99": lat(0.99), "worst": lat(1.0) },
        });
        keyshape_io::write_atomic(p, |w| {
            serde_json::to_writer_pretty(&mut *w, &v).map_err(std::io::Error::other)?;
            w.write_all(b"\n")
        })?;
    }
    Ok(())
}

pub(super) fn ms(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{v:.2} ms"))
}
