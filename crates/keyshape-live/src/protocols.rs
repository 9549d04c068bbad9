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

/// A device id as Live Link Face sends one: a UUID, 36 characters (`8-4-4-4-12` hex
/// digits, version 4). Decoders written against the app (PyLiveLinkFace and the tools
/// built on it) read a fixed 36 characters after the length, so a shorter id shifts every
/// field after it. Made from `seed` (the session's start and process id), so each session
/// is a device of its own.
pub fn device_uuid(seed: u128) -> String {
    // Two rounds of a 64-bit mix (splitmix64) over the seed's halves.
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let (hi, lo) = ((seed >> 64) as u64, seed as u64);
    let a = mix(hi ^ mix(lo));
    let b = mix(a ^ lo);
    // Version 4, variant 10xx.
    let a = (a & !0xF000) | 0x4000;
    let b = (b & !(0xC000 << 48)) | (0x8000 << 48);
    format!(
        "{:08x}-{:04x}-{:04x}-{:04x}-{:012x}",
        a >> 32,
        (a >> 16) & 0xFFFF,
        a & 0xFFFF,
        b >> 48,
        b & 0xFFFF_FFFF_FFFF
    )
}

/// The head's rotation as a unit quaternion (x, y, z, w) in the rig's own axes — x the
/// person's left, y up, z the way the face looks, right-handed — from its yaw, pitch and
/// roll (radians, as [`Camera::yaw_pitch_roll`](keyshape_rig::camera::Camera::yaw_pitch_roll)
/// gives them: positive yaw turns the face to the person's left, positive pitch tips it
/// down, positive roll tilts its top to the person's right), applied roll, then pitch, then
/// yaw.
pub fn head_quaternion(yaw_pitch_roll: [f64; 3]) -> [f32; 4] {
    let [yaw, pitch, roll] = yaw_pitch_roll;
    let q = nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), yaw)
        * nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), pitch)
        * nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), roll);
    [q.i as f32, q.j as f32, q.k as f32, q.w as f32]
}

/// The head's rotation as a VMC receiver applies it: Unity's axes are left-handed, x the
/// avatar's right, y up, z the way it faces, and a receiver sets the rotation as the head
/// bone's local rotation (EVMC4U's `BoneSynchronizeSingle`). The rig's axes have x the
/// person's left: the same turn in Unity's axes is the reflection of x, which keeps the
/// quaternion's x and negates its y and z. So the avatar turns to its own left when the
/// person turns to theirs. `mirror`: the avatar is the person's reflection instead (it
/// turns to its right), the quaternion as the rig's axes have it.
pub fn vmc_head(yaw_pitch_roll: [f64; 3], mirror: bool) -> [f32; 4] {
    let [x, y, z, w] = head_quaternion(yaw_pitch_roll);
    if mirror {
        [x, y, z, w]
    } else {
        [x, -y, -z, w]
    }
}

/// Per rig shape, the shape that is its mirror image: a `_L` shape's `_R` twin (ICT's
/// `mouthSmile_L`), a `…Left` shape's `…Right` (ARKit's `jawLeft`, `eyeBlinkLeft`), and
/// itself for a shape with no side or no twin in the rig.
pub fn mirror_shapes(names: &[String]) -> Vec<usize> {
    let twin_name = |n: &str| -> Option<String> {
        for (a, b) in [("_L", "_R"), ("_R", "_L"), ("_l", "_r"), ("_r", "_l")] {
            if let Some(stem) = n.strip_suffix(a) {
                return Some(format!("{stem}{b}"));
            }
        }
        for (a, b) in [("Left", "Right"), ("Right", "Left")] {
            if let Some(at) = n.rfind(a) {
                return Some(format!("{}{b}{}", &n[..at], &n[at + a.len()..]));
            }
        }
        None
    };
    (0..names.len())
        .map(|s| {
            twin_name(&names[s])
                .and_then(|t| names.iter().position(|n| *n == t))
                .unwrap_or(s)
        })
        .collect()
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
/// `/VMC/Ext/Blend/Apply`, then, with a head, `/VMC/Ext/Bone/Pos` "Head" — its local
/// position (metres, Unity's axes) and rotation ([`vmc_head`]) —, time tag "immediately".
pub fn vmc_bundle(names: &[String], values: &[f64], head: Option<([f32; 3], [f32; 4])>) -> Vec<u8> {
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
    if let Some((position, rotation)) = head {
        let mut bone = vec![OscType::String("Head".into())];
        bone.extend(position.map(OscType::Float));
        bone.extend(rotation.map(OscType::Float));
        content.push(OscPacket::Message(OscMessage {
            addr: "/VMC/Ext/Bone/Pos".into(),
            args: bone,
        }));
    }
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

#[cfg(test)]
mod tests {
    /// A device id is a version-4 UUID of 36 characters, a different one per seed.
    #[test]
    fn a_device_id_is_a_uuid() {
        let mut seen = std::collections::HashSet::new();
        for seed in [0u128, 1, 2, u128::MAX, 1 << 64, 12345 << 70] {
            let id = super::device_uuid(seed);
            assert_eq!(id.len(), 36, "{id}");
            let parts: Vec<&str> = id.split('-').collect();
            assert_eq!(
                parts.iter().map(|p| p.len()).collect::<Vec<_>>(),
                [8, 4, 4, 4, 12]
            );
            assert!(id.chars().all(|c| c == '-' || c.is_ascii_hexdigit()));
            assert!(parts[2].starts_with('4'), "version 4: {id}");
            assert!("89ab".contains(&parts[3][..1]), "variant: {id}");
            assert!(seen.insert(id));
        }
    }
}
