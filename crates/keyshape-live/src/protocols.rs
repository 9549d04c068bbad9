//! What the sinks send: Live Link Face UDP packets and VMC bundles (OSC).

use keyshape_rig::livelink::{arkit_name, COLUMNS};
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

/// Live Link Face's UDP packet (version 6), as the iOS app sends it to Unreal's Live Link
/// (port 11111), every number big-endian:
///
/// | bytes | field |
/// |---|---|
/// | 1 | u8 version = 6 |
/// | 4 + n | i32 length, then the device id (UTF-8) |
/// | 4 + n | i32 length, then the subject name (UTF-8) |
/// | 4 | i32 frame number |
/// | 4 | f32 sub-frame |
/// | 4 + 4 | i32 frame rate numerator, denominator |
/// | 1 | u8 value count = 61 |
/// | 61 × 4 | f32 values, in [`COLUMNS`] order |
pub fn livelink_packet(
    device: &str,
    subject: &str,
    frame: i32,
    fps: i32,
    values: &[f64; 61],
) -> Vec<u8> {
    let mut out = Vec::with_capacity(1 + 8 + device.len() + subject.len() + 17 + 61 * 4);
    out.push(6u8);
    for s in [device, subject] {
        out.extend_from_slice(&(s.len() as i32).to_be_bytes());
        out.extend_from_slice(s.as_bytes());
    }
    out.extend_from_slice(&frame.to_be_bytes());
    out.extend_from_slice(&0f32.to_be_bytes());
    out.extend_from_slice(&fps.to_be_bytes());
    out.extend_from_slice(&1i32.to_be_bytes());
    out.push(61u8);
    for v in values {
        out.extend_from_slice(&(*v as f32).to_be_bytes());
    }
    out
}

/// The head's rotation as a unit quaternion (x, y, z, w) from its yaw, pitch and roll
/// (radians, as the Live Link columns and `kslab rig --pose` give them): yaw about the
/// vertical axis, pitch about the sideways axis, roll about the view axis, applied roll,
/// then pitch, then yaw.
pub fn head_quaternion(yaw_pitch_roll: [f64; 3]) -> [f32; 4] {
    let [yaw, pitch, roll] = yaw_pitch_roll;
    let q = nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), yaw)
        * nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), pitch)
        * nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), roll);
    [q.i as f32, q.j as f32, q.k as f32, q.w as f32]
}

/// The names a VMC receiver's Perfect Sync avatar gives the rig's values, in the order
/// [`vmc_values`] sends them: the 52 ARKit shapes (`EyeBlinkLeft` … `TongueOut`), then the
/// rig's shapes that are none of them under their ARKit-style name (ICT's
/// `cheekRaiser_L` → `CheekRaiserLeft`).
pub fn vmc_names(rig_names: &[String], sources: &[Vec<usize>]) -> Vec<String> {
    let mut names: Vec<String> = COLUMNS[..52].iter().map(|c| c.to_string()).collect();
    for (s, n) in rig_names.iter().enumerate() {
        if !sources.iter().any(|src| src.contains(&s)) {
            names.push(arkit_name(n));
        }
    }
    names
}

/// The values [`vmc_names`] names, for the weights `w` (rig order): the first 52 as the Live
/// Link columns take them, then the rig's own.
pub fn vmc_values(sources: &[Vec<usize>], w: &[f64]) -> Vec<f64> {
    let values = keyshape_rig::livelink::frame_values(sources, w, [0.0; 3]);
    let mut out = values[..52].to_vec();
    for (s, v) in w.iter().enumerate() {
        if !sources.iter().any(|src| src.contains(&s)) {
            out.push(*v);
        }
    }
    out
}

/// One frame as a VMC bundle: `/VMC/Ext/Blend/Val` (name, value) for every name, then
/// `/VMC/Ext/Blend/Apply`, then the head as `/VMC/Ext/Bone/Pos` "Head" (position 0, the
/// rotation of [`head_quaternion`]), time tag "immediately".
pub fn vmc_bundle(names: &[String], values: &[f64], head: [f32; 4]) -> Vec<u8> {
    let mut content: Vec<OscPacket> = names
        .iter()
        .zip(values)
        .map(|(n, v)| {
            OscPacket::Message(OscMessage {
                addr: "/VMC/Ext/Blend/Val".into(),
                args: vec![OscType::String(n.clone()), OscType::Float(*v as f32)],
            })
        })
        .collect();
    content.push(OscPacket::Message(OscMessage {
        addr: "/VMC/Ext/Blend/Apply".into(),
        args: Vec::new(),
    }));
    let mut bone = vec![OscType::String("Head".into())];
    bone.extend([0.0f32, 0.0, 0.0].map(OscType::Float));
    bone.extend(head.map(OscType::Float));
    content.push(OscPacket::Message(OscMessage {
        addr: "/VMC/Ext/Bone/Pos".into(),
        args: bone,
    }));
    let bundle = OscPacket::Bundle(OscBundle {
        timetag: OscTime {
            seconds: 0,
            fractional: 1,
        },
        content,
    });
    // rosc's encoder writes into a Vec, which cannot fail.
    rosc::encoder::encode(&bundle).unwrap_or_default()
}
