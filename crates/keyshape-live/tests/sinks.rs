//! The sinks as receivers read them: a VMC bundle as EVMC4U applies it (Unity's axes), a
//! Live Link packet at the fixed offsets PyLiveLinkFace-style decoders read, and the
//! mirror flipping head and face together.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_live::sink::{SinkOptions, SinkSpec, Sinks};
use keyshape_rig::Rig;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

fn rig() -> Rig {
    Rig::read_ict(&keyshape_io::shared_data("ict_facekit_face").unwrap()).unwrap()
}

/// The head bone as sent: local position, local rotation (x, y, z, w).
type Bone = ([f32; 3], [f32; 4]);

/// One frame through a VMC sink: (blend values by name, the head bone).
fn vmc_frame(
    options: SinkOptions,
    w: &[f64],
    head: [f64; 3],
) -> (Vec<(String, f32)>, Option<Bone>) {
    let recv = UdpSocket::bind("127.0.0.1:0").unwrap();
    recv.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let spec = SinkSpec::Vmc(recv.local_addr().unwrap());
    let mut sinks = Sinks::open(&[spec], &rig(), Box::new(std::io::sink()), 30.0, options).unwrap();
    sinks.send(0, (w, head), Instant::now(), true).unwrap();
    let mut buf = vec![0u8; 65_536];
    let n = recv.recv(&mut buf).unwrap();
    let rosc::OscPacket::Bundle(b) = rosc::decoder::decode_udp(&buf[..n]).unwrap().1 else {
        panic!("a bundle")
    };
    let mut vals = Vec::new();
    let mut bone = None;
    for p in b.content {
        let rosc::OscPacket::Message(m) = p else {
            panic!("flat")
        };
        let f = |i: usize| match m.args[i] {
            rosc::OscType::Float(v) => v,
            _ => panic!("a float"),
        };
        match m.addr.as_str() {
            "/VMC/Ext/Blend/Val" => {
                let rosc::OscType::String(name) = &m.args[0] else {
                    panic!("a name")
                };
                vals.push((name.clone(), f(1)));
            }
            "/VMC/Ext/Bone/Pos" => bone = Some(([f(1), f(2), f(3)], [f(4), f(5), f(6), f(7)])),
            _ => {}
        }
    }
    (vals, bone)
}

/// Where a Unity avatar's face points under the local rotation (x, y, z, w): x its right.
fn facing(q: [f32; 4]) -> [f64; 3] {
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        f64::from(q[3]),
        f64::from(q[0]),
        f64::from(q[1]),
        f64::from(q[2]),
    ));
    let v = q * nalgebra::Vector3::z();
    [v.x, v.y, v.z]
}

/// The person smiles on their left and turns to their left: by default the avatar smiles
/// on its left and faces its left (−x); mirrored, it smiles on its right and faces its
/// right, head and face flipped together. The head bone sits where the options put it.
#[test]
fn the_avatar_turns_and_smiles_on_the_persons_side_unless_mirrored() {
    let rig = rig();
    let mut w = vec![0.0; rig.k()];
    w[rig.names.iter().position(|n| n == "mouthSmile_L").unwrap()] = 0.8;
    let yaw = 0.4;
    let value = |vals: &[(String, f32)], n: &str| vals.iter().find(|v| v.0 == n).unwrap().1;
    let (vals, bone) = vmc_frame(SinkOptions::default(), &w, [yaw, 0.0, 0.0]);
    let (pos, rot) = bone.unwrap();
    assert_eq!(pos, [0.0, 0.1, 0.0]);
    assert_eq!(
        (
            value(&vals, "MouthSmileLeft"),
            value(&vals, "MouthSmileRight")
        ),
        (0.8, 0.0)
    );
    let f = facing(rot);
    assert!((f[0] + yaw.sin()).abs() < 1e-6, "faces its left: {f:?}");
    let mirrored = SinkOptions {
        mirror: true,
        head_position: Some([0.0, 0.07, 0.01]),
    };
    let (vals, bone) = vmc_frame(mirrored, &w, [yaw, 0.0, 0.0]);
    let (pos, rot) = bone.unwrap();
    assert_eq!(pos, [0.0, 0.07, 0.01]);
    assert_eq!(
        (
            value(&vals, "MouthSmileLeft"),
            value(&vals, "MouthSmileRight")
        ),
        (0.0, 0.8)
    );
    let f = facing(rot);
    assert!((f[0] - yaw.sin()).abs() < 1e-6, "faces its right: {f:?}");
    // A nod down is a nod down either way; no bone when asked for none.
    for mirror in [false, true] {
        let o = SinkOptions {
            mirror,
            head_position: None,
        };
        let (_, bone) = vmc_frame(o, &w, [0.0, 0.3, 0.0]);
        assert!(bone.is_none());
        let (_, bone) = vmc_frame(
            SinkOptions {
                mirror,
                ..SinkOptions::default()
            },
            &w,
            [0.0, 0.3, 0.0],
        );
        let f = facing(bone.unwrap().1);
        assert!((f[1] + 0.3f64.sin()).abs() < 1e-6, "{f:?}");
    }
}
