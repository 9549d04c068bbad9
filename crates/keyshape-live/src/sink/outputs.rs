//! The sinks `--to` names: VMC bundles and Live Link Face packets over UDP, and the
//! weights table on standard output.

use super::{csv_line, weights_header, weights_line, Sent, Sink, SinkOptions};
use crate::protocols::{
    livelink_packet, mirror_shapes, vmc_bundle, vmc_head, vmc_names, vmc_values,
};
use keyshape_core::error::{setting, Error, Result};
use keyshape_rig::livelink::{column_sources, frame_values};
use keyshape_rig::Rig;
use std::io::Write;
use std::net::{SocketAddr, UdpSocket};

/// A UDP socket to send to `to` from.
fn socket(to: SocketAddr) -> Result<UdpSocket> {
    let any = if to.is_ipv6() { "[::]:0" } else { "0.0.0.0:0" };
    UdpSocket::bind(any)
        .map_err(|e| Error::invalid(format!("{}: cannot open a UDP socket: {e}", setting("to"))))
}

/// How an avatar is shown the frame: the person's own sides, or (mirrored) each shape
/// taking its twin's value and the turn and tilt flipped.
struct Presenter {
    mirror: bool,
    twins: Vec<usize>,
}

impl Presenter {
    fn new(rig: &Rig, options: SinkOptions) -> Presenter {
        Presenter {
            mirror: options.mirror,
            twins: mirror_shapes(&rig.names),
        }
    }

    fn show(&self, f: &Sent) -> (Vec<f64>, [f64; 3]) {
        if self.mirror {
            let w = self.twins.iter().map(|&t| f.weights[t]).collect();
            (w, [-f.head[0], f.head[1], -f.head[2]])
        } else {
            (f.weights.clone(), f.head)
        }
    }
}

/// VMC bundles (OSC over UDP): the blend values, Apply, the head bone.
pub struct VmcSink {
    udp: UdpSocket,
    to: SocketAddr,
    show: Presenter,
    head_position: Option<[f32; 3]>,
    sources: Vec<Vec<usize>>,
    names: Vec<String>,
    refused: u64,
}

impl VmcSink {
    /// A VMC sink sending `rig`'s weights to `to`.
    pub fn open(to: SocketAddr, rig: &Rig, options: SinkOptions) -> Result<VmcSink> {
        let sources = column_sources(rig);
        Ok(VmcSink {
            udp: socket(to)?,
            to,
            show: Presenter::new(rig, options),
            head_position: options.head_position,
            names: vmc_names(&rig.names, &sources),
            sources,
            refused: 0,
        })
    }
}

impl Sink for VmcSink {
    fn name(&self) -> String {
        format!("vmc:{}", self.to)
    }

    fn every_frame(&self) -> bool {
        false
    }

    fn send(&mut self, f: &Sent) -> std::io::Result<()> {
        let (w, _) = self.show.show(f);
        let bone = self
            .head_position
            .map(|p| (p, vmc_head(f.head, self.show.mirror)));
        let bundle = vmc_bundle(&self.names, &vmc_values(&self.sources, &w), bone);
        if self.udp.send_to(&bundle, self.to).is_err() {
            self.refused += 1;
        }
        Ok(())
    }

    fn refused(&self) -> u64 {
        self.refused
    }
}

/// Live Link Face packets over UDP.
pub struct LiveLinkSink {
    udp: UdpSocket,
    to: SocketAddr,
    show: Presenter,
    device: String,
    sources: Vec<Vec<usize>>,
    refused: u64,
}

impl LiveLinkSink {
    /// A Live Link sink sending `rig`'s weights to `to` as device `device` (a UUID).
    pub fn open(
        to: SocketAddr,
        rig: &Rig,
        options: SinkOptions,
        device: String,
    ) -> Result<LiveLinkSink> {
        Ok(LiveLinkSink {
            udp: socket(to)?,
            to,
            show: Presenter::new(rig, options),
            device,
            sources: column_sources(rig),
            refused: 0,
        })
    }
}

impl Sink for LiveLinkSink {
    fn name(&self) -> String {
        format!("livelink:{}", self.to)
    }

    fn every_frame(&self) -> bool {
        false
    }

    fn send(&mut self, f: &Sent) -> std::io::Result<()> {
        let (w, head) = self.show.show(f);
        let values = frame_values(&self.sources, &w, head);
        let packet = livelink_packet(&self.device, "kslab", f.number as i32, f.fps, &values);
        if self.udp.send_to(&packet, self.to).is_err() {
            self.refused += 1;
        }
        Ok(())
    }

    fn refused(&self) -> u64 {
        self.refused
    }
}

/// The weights table (`frame` and the rig's shape names, as `kslab rig` writes it), a line
/// per frame, flushed as it is written.
pub struct TableSink {
    out: Box<dyn Write + Send>,
    header: Option<Vec<String>>,
}

impl TableSink {
    /// A table of `rig`'s weights written to `out`.
    pub fn new(out: Box<dyn Write + Send>, rig: &Rig) -> TableSink {
        TableSink {
            out,
            header: Some(weights_header(rig)),
        }
    }
}

impl Sink for TableSink {
    fn name(&self) -> String {
        "standard output".into()
    }

    fn every_frame(&self) -> bool {
        true
    }

    fn send(&mut self, f: &Sent) -> std::io::Result<()> {
        if let Some(h) = self.header.take() {
            self.out.write_all(&csv_line(h)?)?;
        }
        self.out.write_all(&weights_line(f.number, &f.weights)?)?;
        self.out.flush()
    }
}
