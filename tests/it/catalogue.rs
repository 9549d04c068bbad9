//! The bad-input catalogue: every case is a set of files, a command line, the exact exit
//! code, a piece of the message that names the file / line / value, and the outputs that
//! must not exist afterwards. Each case failed (wrong result, panic or exit 0) before the
//! fix it guards; a new bad input found in the field becomes one more row.

use crate::common::shared;
use std::path::Path;
use std::process::Command;

/// One row of the catalogue. In `args`, `{d}` is the case's temporary directory and
/// `{shared}` the shared data folder.
struct Case {
    name: &'static str,
    files: &'static [(&'static str, &'static str)],
    args: &'static [&'static str],
    code: i32,
    needle: &'static str,
    /// Paths (under `{d}`) that must not exist after the run.
    absent: &'static [&'static str],
}

const MP3: &str = "frame,time_s,detected,x_0,y_0,z_0,x_1,y_1,z_1,x_2,y_2,z_2\n\
                   0,0.0,1,0,0,0,1,0,0,0,1,0\n1,0.1,1,0,0,0,2,0,0,0,1,0\n2,0.2,1,0,0,0,1,0,0,0,2,0\n3,0.3,1,0,0,0,1.5,0,0,0,1.5,0\n";
const PLAIN: &str =
    "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,2,0,0,1\n2,0,0,1,0,0,2\n3,0,0,1.5,0,0,1.5\n";

const CASES: &[Case] = &[
    // ---- readers ----
    Case { name: "missing file", files: &[], args: &["info", "{d}/nope.csv"], code: 1, needle: "nope.csv: No such file", absent: &[] },
    Case { name: "empty file", files: &[("e.csv", "")], args: &["info", "{d}/e.csv"], code: 1, needle: "e.csv: file is empty", absent: &[] },
    Case { name: "no landmark columns", files: &[("n.csv", "frame,a,b\n0,1,2\n")], args: &["info", "{d}/n.csv"], code: 1, needle: "n.csv:1:1: header has no landmark columns", absent: &[] },
    Case { name: "ragged row", files: &[("r.csv", "frame,x0,y0\n0,1,2\n1,1\n")], args: &["info", "{d}/r.csv"], code: 1, needle: "r.csv:3:", absent: &[] },
    Case { name: "text in a number", files: &[("t.csv", "frame,x0,y0\n0,1,abc\n")], args: &["info", "{d}/t.csv"], code: 1, needle: "t.csv:2:3: not a number: 'abc' in column 'y0'", absent: &[] },
    Case { name: "NaN coordinate", files: &[("nan.csv", "frame,x0,y0\n0,NaN,2\n")], args: &["info", "{d}/nan.csv"], code: 1, needle: "nan.csv:2:2: non-finite value 'NaN'", absent: &[] },
    Case { name: "gap in the coordinate header", files: &[("gap.csv", "frame,x0,y0,x1,y1,x3,y3\n0,1,2,3,4,5,6\n")], args: &["info", "{d}/gap.csv"], code: 1, needle: "gap.csv:1:6: header has 'x3' but no 'x2'", absent: &[] },
    Case { name: "renamed coordinate column", files: &[("ren.csv", "frame,detected,x_0,y_0,x_1,yy_1,x_2,y_2\n0,1,1,2,3,4,5,6\n")], args: &["info", "{d}/ren.csv"], code: 1, needle: "ren.csv:1:", absent: &[] },
    Case { name: "a bad value after a blank line names its own line", files: &[("blank.csv", "frame,x0,y0,x1,y1\n0,1,2,3,4\n\n1,1,2,3,oops\n")], args: &["info", "{d}/blank.csv"], code: 1, needle: "blank.csv:4:5: not a number: 'oops' in column 'y1'", absent: &[] },
    Case { name: "CRLF line ends and a blank line: the line is still right", files: &[("crlf.csv", "frame,x0,y0,x1,y1\r\n0,1,2,3,4\r\n\r\n1,1,2,3,oops\r\n")], args: &["info", "{d}/crlf.csv"], code: 1, needle: "crlf.csv:4:5: not a number: 'oops' in column 'y1'", absent: &[] },
    Case { name: "duplicate frame numbers", files: &[("dup.csv", "frame,x0,y0,x1,y1\n0,1,2,3,4\n3,1,2,3,5\n3,1,2,3,6\n")], args: &["info", "{d}/dup.csv"], code: 1, needle: "dup.csv:4:1: frame 3 appears twice (first on line 3)", absent: &[] },
    Case { name: "gzip that is not gzip", files: &[("g.csv.gz", "frame,x0,y0\n0,1,2\n")], args: &["info", "{d}/g.csv.gz"], code: 1, needle: "g.csv.gz: not a valid gzip file", absent: &[] },
    Case { name: "coordinate near 1e200", files: &[("big.csv", "frame,x0,y0,x1,y1\n0,1e200,2,3,4\n1,1,2,3,5\n")], args: &["solve", "{d}/big.csv", "--no-align", "--keys", "0"], code: 1, needle: "big.csv:2:2: coordinate 1e200 is beyond", absent: &[] },
    Case { name: "coordinate 1e308", files: &[("huge.csv", "frame,x0,y0,x1,y1\n0,1e308,1e308,1e308,1e308\n")], args: &["info", "{d}/huge.csv"], code: 1, needle: "huge.csv:2:2: coordinate 1e308 is beyond", absent: &[] },
    Case { name: "all points coincide", files: &[("same.csv", "frame,x0,y0,x1,y1\n0,1,2,3,4\n7,5,5,5,5\n")], args: &["keys", "{d}/same.csv", "--method", "spread", "--k", "1"], code: 1, needle: "same.csv: frame 7: all 2 points coincide", absent: &[] },
    Case { name: "JSON points overflow", files: &[("p.json", r#"{"kslab_sequence":1,"dims":2,"points":9223372036854775876,"frames":[]}"#)], args: &["info", "{d}/p.json"], code: 1, needle: "p.json:", absent: &[] },
    Case { name: "JSON points beyond the limit", files: &[("q.json", r#"{"kslab_sequence":1,"dims":2,"points":4611686018427387904,"frames":[{"frame":0,"valid":false}]}"#)], args: &["info", "{d}/q.json"], code: 1, needle: "q.json: points 4611686018427387904 is too large", absent: &[] },
    Case { name: "JSON duplicate frame", files: &[("d.json", r#"{"kslab_sequence":1,"dims":2,"points":1,"frames":[{"frame":2,"coords":[1,2]},{"frame":2,"coords":[1,3]}]}"#)], args: &["info", "{d}/d.json"], code: 1, needle: "d.json: frames[1] repeats frame number 2", absent: &[] },
    Case { name: "JSON wrong coordinate count", files: &[("c.json", r#"{"kslab_sequence":1,"dims":2,"points":2,"frames":[{"frame":0,"coords":[1,2,3]}]}"#)], args: &["info", "{d}/c.json"], code: 1, needle: "c.json: frames[0] (frame 0) has 3 coords", absent: &[] },
    Case { name: ".pts without closing brace", files: &[("a.pts", "version: 1\nn_points: 2\n{\n1 2\n3 4\n")], args: &["info", "{d}/a.pts"], code: 1, needle: "a.pts", absent: &[] },
    Case { name: ".pts with data after the closing brace (was accepted)", files: &[("b.pts", "version: 1\nn_points: 2\n{\n1 2\n3 4\n}\n5 6\n")], args: &["info", "{d}/b.pts"], code: 1, needle: "b.pts:7:1: '5 6' after the closing '}': a .pts file ends there", absent: &[] },
    Case { name: "an OBJ vertex at 1e308 (was refused later, by a camera fit, without the file)", files: &[("big.obj", "v 1e308 0 0\nv 0 1 0\nv 1 0 0\nf 1 2 3\n")], args: &["transfer", "--mesh", "{d}/big.obj"], code: 1, needle: "big.obj:1:3: coordinate 1e308 is beyond ±1e30", absent: &[] },
    Case { name: "a face offset by 1e15 (was: all points coincide)", files: &[("off.csv", "frame,x0,y0,x1,y1,x2,y2\n0,1e15,1e15,1000000000000050,1e15,1e15,1000000000000050\n1,1e15,1e15,1000000000000060,1e15,1e15,1000000000000050\n")], args: &["keys", "{d}/off.csv", "--method", "spread", "--k", "1"], code: 1, needle: "off.csv: frame 0: the 3 points spread over", absent: &[] },
    Case { name: "smooth on a normalised track with the px² λ grid (did not settle)", files: &[("n.csv", "frame,x0,y0,x1,y1,x2,y2\n0,0.1,0.1,0.2,0.1,0.1,0.2\n1,0.1,0.1,0.3,0.1,0.1,0.2\n2,0.1,0.1,0.2,0.1,0.1,0.3\n")], args: &["smooth", "{d}/n.csv", "--k", "2", "--out", "{d}/sm"], code: 1, needle: "n.csv: the track is in normalised coordinates (every x and y in [0, 1]) and the default λ grid is in px²: give --image-size", absent: &["sm"] },
    Case { name: "directory without .pts", files: &[("dir/readme.txt", "x")], args: &["info", "{d}/dir"], code: 1, needle: "dir: directory holds no .pts files", absent: &[] },
    Case { name: "a device as input", files: &[], args: &["info", "/dev/zero"], code: 1, needle: "/dev/zero: is not a regular file", absent: &[] },
    Case { name: "template naming a point it lacks (found by fuzzing)", files: &[("bad.svg", r#"<svg xmlns="http://www.w3.org/2000/svg"><desc id="kslab-template">{"points":2,"polylines":[[0,5]],"rest":false}</desc><g id="key-0"><polyline id="key-0-c0" points="0,0 1,1"/></g></svg>"#)], args: &["retarget", "--points", "lips", "--target", "{d}/bad.svg"], code: 1, needle: "bad.svg: template description is damaged: a contour names point 5, but the template has 2 points", absent: &[] },
    Case { name: "template with a huge point count", files: &[("big.svg", r#"<svg xmlns="http://www.w3.org/2000/svg"><desc id="kslab-template">{"points":18446744073709551615,"polylines":[[0,1]],"rest":false}</desc></svg>"#)], args: &["retarget", "--points", "lips", "--target", "{d}/big.svg"], code: 1, needle: "big.svg: template description is damaged: points 18446744073709551615 is not a point count", absent: &[] },
    // ---- options ----
    Case { name: "negative key frame", files: &[("mp.csv", MP3)], args: &["solve", "{d}/mp.csv", "--keys", "-1"], code: 1, needle: "--keys -1: frame -1 is out of range: frames run 0..=3", absent: &[] },
    Case { name: "key frame twice", files: &[("mp.csv", MP3)], args: &["solve", "{d}/mp.csv", "--keys", "2,2"], code: 1, needle: "--keys: frame 2 is listed twice", absent: &[] },
    Case { name: "k = u64::MAX", files: &[], args: &["keys", "--method", "spread", "--k", "18446744073709551615"], code: 1, needle: "k = 18446744073709551615 key shapes asked for, but the sequence has only 216 distinct shapes", absent: &[] },
    Case { name: "curves k range to u64::MAX", files: &[], args: &["curves", "--methods", "spread", "--k", "2..18446744073709551615", "--out", "{d}/c.csv"], code: 1, needle: "only 216 distinct shapes", absent: &["c.csv"] },
    Case { name: "hull with --k", files: &[], args: &["keys", "--method", "hull", "--k", "5"], code: 1, needle: "--method hull chooses its own k", absent: &[] },
    Case { name: "--k missing", files: &[], args: &["keys", "--method", "spread"], code: 1, needle: "--k is required for --method spread", absent: &[] },
    Case { name: "--pcs 0", files: &[], args: &["keys", "--method", "kmeans2", "--k", "3", "--pcs", "0"], code: 2, needle: "'--pcs <PCS>'", absent: &[] },
    Case { name: "--pcs with spread", files: &[], args: &["keys", "--method", "spread", "--k", "3", "--pcs", "3"], code: 1, needle: "--pcs applies to k-means only, not to spread", absent: &[] },
    Case { name: "--seed with spread", files: &[], args: &["template", "--method", "spread", "--seed", "3", "--out", "{d}/t.svg"], code: 1, needle: "--seed applies to kmeans and random only", absent: &["t.svg"] },
    Case { name: "--shortlist with ls", files: &[], args: &["keys", "--method", "greedy", "--k", "3", "--solver", "ls", "--shortlist", "4"], code: 1, needle: "--shortlist applies to greedy with the nnls or bounded solver only", absent: &[] },
    Case { name: "--every 0", files: &[], args: &["transfer", "--mesh", "{shared}/mediapipe_canonical_face/canonical_face_model.obj", "--every", "0"], code: 2, needle: "'--every <EVERY>'", absent: &[] },
    Case { name: "--trace-noise NaN", files: &[], args: &["retarget", "--trace-noise", "NaN"], code: 1, needle: "--trace-noise NaN is not a fraction", absent: &[] },
    Case { name: "--trace-noise 1e300", files: &[], args: &["retarget", "--trace-noise", "1e300"], code: 1, needle: "--trace-noise 1e300 is not a fraction", absent: &[] },
    Case { name: "--regions with --k", files: &[], args: &["retarget", "--regions", "builtin", "--k", "3", "--out", "{d}/w.csv"], code: 1, needle: "--regions gives each region its own k", absent: &["w.csv"] },
    Case { name: "--head-motion with --no-align", files: &[], args: &["retarget", "--no-align", "--head-motion", "none"], code: 1, needle: "--head-motion does not apply with --no-align", absent: &[] },
    Case { name: "info --no-align", files: &[], args: &["info", "--no-align"], code: 1, needle: "--no-align does not apply to info", absent: &[] },
    Case { name: "map --apng without a second person", files: &[], args: &["map", "--actions", "assets/actions/actions_liveportrait_d6.json", "--out", "{d}/m.csv", "--apng", "{d}/m.png"], code: 2, needle: "--target-sequence", absent: &["m.csv", "m.png"] },
    Case { name: "map with nothing to do", files: &[], args: &["map", "--actions", "assets/actions/actions_liveportrait_d6.json"], code: 1, needle: "nothing to do", absent: &[] },
    // (A MediaPipe track onto the ICT mesh was refused here until
    // `mediapipe_to_ict` was made from the rig's 468 → 68 correspondence; a track of a layout no
    // correspondence knows still is.)
    Case { name: "transfer: a track of no known layout onto the ICT mesh", files: &[("three.csv", PLAIN)], args: &["transfer", "{d}/three.csv", "--mesh", "{shared}/ict_facekit_face/neutral_face.obj", "--obj-dir", "{d}/objs"], code: 1, needle: "no built-in feature correspondence fits a 3-point track onto a 9409-vertex mesh", absent: &["objs"] },
    Case { name: "transfer: features for another layout", files: &[], args: &["transfer", "{shared}/pyfeat_samples/news_sample_compact.csv", "--mesh", "{shared}/ict_facekit_face/neutral_face.obj", "--features", "mediapipe_to_canonical"], code: 1, needle: "features mediapipe_to_canonical are for 468-point mediapipe_face_mesh_468 tracks", absent: &[] },
    Case { name: "TOML k = true", files: &[("e.toml", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = true\n")], args: &["run", "{d}/e.toml", "--out", "{d}/out"], code: 1, needle: "e.toml:4:5: not a k range", absent: &["out"] },
    Case { name: "TOML compare_raw without alignment", files: &[("c.toml", "title = \"x\"\ninput = \"builtin\"\nalign = false\nmethods = [\"spread\"]\ncompare_raw = true\n")], args: &["run", "{d}/c.toml", "--out", "{d}/out"], code: 1, needle: "c.toml:5:1: compare_raw: compares aligned with raw curves", absent: &["out"] },
    Case { name: "TOML blend_radius with disjoint", files: &[("b.toml", "title = \"x\"\ninput = \"builtin\"\n[modes]\nactions = \"a.json\"\nboundary = \"disjoint\"\nblend_radius = 0.2\n")], args: &["run", "{d}/b.toml", "--out", "{d}/out"], code: 1, needle: "b.toml:6:1: blend_radius: a blend radius applies only to blended", absent: &["out"] },
    Case { name: "TOML neutral_frames with causal centring", files: &[("n.toml", "title = \"x\"\ninput = \"builtin\"\n[intensity]\ncentring = \"causal\"\nneutral_frames = 3\n")], args: &["run", "{d}/n.toml", "--out", "{d}/out"], code: 1, needle: "n.toml:5:1: neutral_frames: neutral frames apply only to neutral centring", absent: &["out"] },
    Case { name: "TOML k from 0", files: &[("z.toml", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = \"0..3\"\n")], args: &["run", "{d}/z.toml", "--out", "{d}/out"], code: 1, needle: "z.toml:4:1: k: range 0..3 is empty or starts at 0", absent: &["out"] },
    Case { name: "map --modes 0 (panicked)", files: &[], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--modes", "0", "--out", "{d}/m.csv"], code: 1, needle: "needs at least 1 mode (--modes)", absent: &["m.csv"] },
    Case { name: "modes --blend-radius with --boundary disjoint", files: &[], args: &["modes", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--boundary", "disjoint", "--blend-radius", "0.1", "--png", "{d}/t.png"], code: 1, needle: "blend radius applies only to blended", absent: &["t.png"] },
    Case { name: "map --blend-radius -1", files: &[], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--blend-radius=-1", "--out", "{d}/m.csv"], code: 1, needle: "blend radius -1 must be a finite number", absent: &["m.csv"] },
    Case { name: "map --normalisation both", files: &[], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--normalisation", "both", "--out", "{d}/m.csv"], code: 2, needle: "choose two-sided or one-sided", absent: &["m.csv"] },
    Case { name: "modes regions cover an unknown region", files: &[("r.json", r#"{"layout": "mediapipe_face_mesh_468", "regions": {"lips": ["lips"]}, "cover": ["cheeks"]}"#)], args: &["modes", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--regions", "{d}/r.json"], code: 1, needle: "cover names region 'cheeks'", absent: &[] },
    Case { name: "intensity --neutral-frames without neutral centring", files: &[], args: &["intensity", "--centring", "causal", "--neutral-frames", "3"], code: 1, needle: "neutral frames apply only to neutral centring, not to causal", absent: &[] },
    Case { name: "intensity --train-clips with leave-one-clip-out", files: &[], args: &["intensity", "--evaluation", "leave-one-clip-out", "--train-clips", "1..5"], code: 1, needle: "train clips apply to the split evaluation", absent: &[] },
    Case { name: "solve --smooth -1", files: &[], args: &["solve", "--keys", "0,50,100", "--smooth", "-1", "--out", "{d}/w.csv"], code: 1, needle: "smoothing λ must be a finite number ≥ 0, got -1", absent: &["w.csv"] },
    Case { name: "solve --smooth nan", files: &[], args: &["solve", "--keys", "0,50,100", "--smooth", "nan", "--out", "{d}/w.csv"], code: 1, needle: "smoothing λ must be a finite number ≥ 0, got NaN", absent: &["w.csv"] },
    Case { name: "solve --smooth-order 3", files: &[], args: &["solve", "--keys", "0,50,100", "--smooth", "1", "--smooth-order", "3", "--out", "{d}/w.csv"], code: 1, needle: "smoothing order must be 1 (first difference) or 2", absent: &["w.csv"] },
    Case { name: "solve --smooth-mode without --smooth", files: &[], args: &["solve", "--keys", "0,50,100", "--smooth-mode", "causal", "--out", "{d}/w.csv"], code: 2, needle: "--smooth <LAMBDA>", absent: &["w.csv"] },
    Case { name: "modes --modes 0", files: &[], args: &["modes", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--modes", "0"], code: 1, needle: "needs at least 1 mode (--modes)", absent: &[] },
    Case { name: "intensity --threshold NaN", files: &[], args: &["intensity", "--threshold", "NaN"], code: 1, needle: "threshold NaN must lie in (0, 1)", absent: &[] },
    // ---- outputs ----
    Case { name: "solve --out onto its input", files: &[("x.csv", PLAIN)], args: &["solve", "{d}/x.csv", "--keys", "0", "--out", "{d}/x.csv"], code: 1, needle: "x.csv: refusing to write: this is the input file", absent: &[] },
    Case { name: "curves --out onto its input", files: &[("x.csv", PLAIN)], args: &["curves", "{d}/x.csv", "--methods", "spread", "--k", "1..2", "--out", "{d}/x.csv"], code: 1, needle: "refusing to write: this is the input file", absent: &[] },
    Case { name: "template --out onto its input", files: &[("x.csv", PLAIN)], args: &["template", "{d}/x.csv", "--method", "spread", "--k", "2", "--out", "{d}/x.csv"], code: 1, needle: "refusing to write: this is the input file", absent: &[] },
    Case { name: "output in a missing directory", files: &[], args: &["solve", "--keys", "3", "--out", "{d}/no/such/w.csv"], code: 1, needle: "cannot write: directory", absent: &["no"] },
    Case { name: "output under a file", files: &[("f", "x")], args: &["solve", "--keys", "3", "--out", "{d}/f/w.csv"], code: 1, needle: "is not a directory", absent: &[] },
    Case { name: "output is a directory", files: &[("sub/x", "x")], args: &["solve", "--keys", "3", "--out", "{d}/sub"], code: 1, needle: "sub: is a directory; give a file name", absent: &[] },
    Case { name: "second output unwritable: the first is not written", files: &[("f", "x")], args: &["curves", "--methods", "spread", "--k", "2..3", "--out", "{d}/c.csv", "--png", "{d}/f/c.png"], code: 1, needle: "is not a directory", absent: &["c.csv"] },
    Case { name: "png dir under a file", files: &[("f", "x")], args: &["retarget", "--points", "lips", "--k", "3", "--out", "{d}/w.csv", "--png-dir", "{d}/f/frames"], code: 1, needle: "cannot make this directory", absent: &["w.csv"] },
    Case { name: "two outputs, one path", files: &[], args: &["curves", "--methods", "spread", "--k", "2..3", "--out", "{d}/c", "--png", "{d}/c"], code: 1, needle: "named as two outputs", absent: &["c"] },
    Case { name: "a device as output (was written into)", files: &[], args: &["solve", "--keys", "3", "--out", "/dev/full"], code: 1, needle: "/dev/full: is a device: kslab writes regular files, /dev/null or standard output", absent: &[] },
    // ---- counts bounded and options checked in experiment files ----
    Case { name: "TOML bootstrap 2^61 (panicked)", files: &[("b.toml", "title = \"x\"\ninputs = [\"{shared}/mediapipe_face_tracks/liveportrait_d6.csv\"]\nmethods = [\"spread\"]\nk = \"2..3\"\nbootstrap = 2305843009213693952\n")], args: &["run", "{d}/b.toml", "--out", "{d}/out"], code: 1, needle: "b.toml:5:1: bootstrap: 2305843009213693952 resamples: give 1 to 100000", absent: &["out"] },
    Case { name: "TOML rig frames 10^12 (ran for ever)", files: &[("r.toml", "title = \"x\"\ninput = \"builtin\"\n[rig]\nframes = 1000000000000\n")], args: &["run", "{d}/r.toml", "--out", "{d}/out"], code: 1, needle: "r.toml:4:1: frames: 1000000000000 frames: give 1 to 1000000", absent: &["out"] },
    Case { name: "TOML a method twice", files: &[("m.toml", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\", \"spread\"]\nk = \"2..3\"\n")], args: &["run", "{d}/m.toml", "--out", "{d}/out"], code: 1, needle: "m.toml:3:1: methods: spread is listed twice", absent: &["out"] },
    Case { name: "TOML seed with spread", files: &[("s.toml", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = \"2..3\"\nseed = 3\n")], args: &["run", "{d}/s.toml", "--out", "{d}/out"], code: 1, needle: "s.toml:5:1: seed: applies to kmeans and random", absent: &["out"] },
    Case { name: "TOML shortlist with ls", files: &[("l.toml", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"greedy\"]\nk = \"2..3\"\nsolvers = [\"ls\"]\nshortlist = 3\n")], args: &["run", "{d}/l.toml", "--out", "{d}/out"], code: 1, needle: "l.toml:6:1: shortlist: applies to greedy with the nnls or bounded solver only", absent: &["out"] },
    Case { name: "TOML trace_noise 5", files: &[("t.toml", "title = \"x\"\ninput = \"builtin\"\n[retarget]\nmethod = \"spread\"\nk = 3\nsolvers = [\"nnls\"]\ntrace_noise = [5.0]\n")], args: &["run", "{d}/t.toml", "--out", "{d}/out"], code: 1, needle: "t.toml:7:1: trace_noise: 5.0 is not a fraction", absent: &["out"] },
    Case { name: "TOML without input: no line 0", files: &[("i.toml", "title = \"x\"\nmethods = [\"spread\"]\n")], args: &["run", "{d}/i.toml", "--out", "{d}/out"], code: 1, needle: "i.toml: input: missing", absent: &["out"] },
    Case { name: "solve --rcond with nnls (had no effect)", files: &[], args: &["solve", "--keys", "3,50", "--rcond", "0.1", "--out", "{d}/w.csv"], code: 1, needle: "--rcond is the least-squares cutoff: it does not apply to --solver nnls", absent: &["w.csv"] },
    Case { name: "rig --rig that does not exist (was: needs --rig-landmarks)", files: &[], args: &["rig", "--rig", "{d}/nonexistent", "--out", "{d}/w.csv"], code: 1, needle: "nonexistent: no such folder or file", absent: &["w.csv"] },
    Case { name: "a key frame the file skips (was: out of range)", files: &[("gap.csv", "frame,x0,y0,x1,y1\n0,0,0,1,0\n1,0,0,2,1\n3,0,0,1,2\n")], args: &["solve", "{d}/gap.csv", "--no-align", "--keys", "2", "--out", "{d}/w.csv"], code: 1, needle: "frame 2 is not in the file: its frame numbers skip from 1 to 3", absent: &["w.csv"] },
    Case { name: "intensity on a file read without clips (was: no `clip` column)", files: &[], args: &["intensity", "{shared}/pyfeat_samples/openface_test.csv"], code: 1, needle: "read with the openface reader, which keeps no `clip` column", absent: &[] },
    Case { name: "actions on a track of no known layout", files: &[("three.csv", PLAIN)], args: &["actions", "{d}/three.csv", "--out", "{d}/a.json"], code: 1, needle: "three.csv: actions are chosen on MediaPipe (468 or 478 points) or iBUG-68 tracks, not 3 points", absent: &["a.json"] },
    // ---- every file a command touches is in its output set (round three) ----
    Case { name: "map --out into the --morph folder", files: &[("ict/expressions.csv", "name\n"), ("ict/landmarks_multipie68.csv", "landmark,vertex\n")], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--morph", "{d}/ict", "--out", "{d}/ict/expressions.csv"], code: 1, needle: "ict/expressions.csv: refusing to write: this is the input file", absent: &[] },
    Case { name: "map --morph-gltf onto a rig file map does not read", files: &[("ict/expressions.csv", "name\n"), ("ict/landmarks_multipie68.csv", "landmark,vertex\n")], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--morph", "{d}/ict", "--morph-gltf", "{d}/ict/landmarks_multipie68.csv"], code: 1, needle: "landmarks_multipie68.csv: refusing to write: this is the input file", absent: &[] },
    Case { name: "map --out onto its --mapping", files: &[("ict/expressions.csv", "name\n"), ("M.json", "{}")], args: &["map", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--morph", "{d}/ict", "--mapping", "{d}/M.json", "--out", "{d}/M.json"], code: 1, needle: "M.json: refusing to write: this is the input file", absent: &[] },
    Case { name: "merge --out spelled through .. into a shard folder", files: &[("s0/x", ""), ("s1/x", "")], args: &["merge", "{d}/s0", "{d}/s1", "--out", "{d}/o1/../s1/"], code: 1, needle: "would overwrite a shard's folder", absent: &["o1"] },
    Case { name: "two outputs on standard output", files: &[], args: &["solve", "--keys", "3", "--out", "-", "--png", "-"], code: 1, needle: "both would go to standard output", absent: &[] },
    Case { name: "the default standard output and --png -", files: &[], args: &["solve", "--keys", "3", "--png", "-"], code: 1, needle: "both would go to standard output", absent: &[] },
    Case { name: "hull on two identical frames (panicked)", files: &[("twin.csv", "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,1,0,0,1\n")], args: &["keys", "{d}/twin.csv", "--no-align", "--method", "hull"], code: 1, needle: "the convex hull (--method hull) needs at least 2 distinct shapes, but the sequence has 1 (2 frames, the rest repeats)", absent: &[] },
    Case { name: "solve with hull on two identical frames (panicked)", files: &[("twin.csv", "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,1,0,0,1\n")], args: &["solve", "{d}/twin.csv", "--no-align", "--method", "hull", "--out", "{d}/w.csv"], code: 1, needle: "needs at least 2 distinct shapes", absent: &["w.csv"] },
    // ---- kslab live: bad options fail before anything starts ----
    Case { name: "live: an unknown source scheme", files: &[], args: &["live", "--from", "webcam:0", "--to", "stdout"], code: 1, needle: "--from 'webcam:0': not a source", absent: &[] },
    Case { name: "live: a source port out of range", files: &[], args: &["live", "--from", "openseeface:70000", "--to", "vmc"], code: 1, needle: "port '70000' is not a port number", absent: &[] },
    Case { name: "live: a sink port of 0", files: &[], args: &["live", "--from", "openseeface", "--to", "vmc:0"], code: 1, needle: "--to vmc:0: port '0'", absent: &[] },
    Case { name: "live: no sink", files: &[], args: &["live", "--from", "openseeface"], code: 1, needle: "--to: name where the weights go", absent: &[] },
    Case { name: "live: standard input empty", files: &[], args: &["live", "--from", "stdin", "--to", "stdout"], code: 1, needle: "stdin: ended before its first line", absent: &[] },
    Case { name: "live: a track no rig reads", files: &[("p.csv", PLAIN)], args: &["live", "--from", "file:{d}/p.csv", "--to", "stdout", "--record", "{d}/take"], code: 1, needle: "this one has 3 points", absent: &["take"] },
    Case { name: "live: an image size for a track in pixels", files: &[("p.csv", PLAIN)], args: &["live", "--from", "file:{d}/p.csv", "--to", "stdout", "--image-size", "10x10"], code: 1, needle: "an image size applies to normalised coordinates", absent: &[] },
    Case { name: "live: --rate on a live source", files: &[], args: &["live", "--from", "openseeface", "--to", "stdout", "--rate", "30"], code: 1, needle: "--rate applies to a file source", absent: &[] },
    // ---- round four (issue 65): the live path's files, streams, bounds ----
    Case { name: "live: --stats is a file of the take (was: the take's weights replaced by the stats)", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--record", "{d}/take", "--stats", "{d}/take/weights.csv"], code: 1, needle: "take/weights.csv: named as two outputs", absent: &["take"] },
    Case { name: "live: --neutral-file is a file of the take (was: the recorded track replaced)", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--record", "{d}/take2", "--neutral-file", "{d}/take2/track.csv"], code: 1, needle: "take2/track.csv: named as two outputs", absent: &["take2"] },
    Case { name: "live: --stats is the calibration to load (was: the calibration lost)", files: &[("t.csv", PLAIN), ("cal.json", "{}")], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--neutral-file", "{d}/cal.json", "--stats", "{d}/cal.json"], code: 1, needle: "cal.json: refusing to write: this is the input file", absent: &[] },
    Case { name: "live: --stats in a missing folder (was: refused after the session)", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--stats", "{d}/no/s.json"], code: 1, needle: "s.json: cannot write: directory", absent: &[] },
    Case { name: "live: --stats - beside --to stdout", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--stats", "-"], code: 1, needle: "both would go to standard output", absent: &[] },
    Case { name: "live: --neutral-file - beside --to stdout", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--neutral-file", "-"], code: 1, needle: "--neutral-file -: a calibration is a file", absent: &[] },
    Case { name: "live: --rate 1e-20 (was: the reader thread panicked and the session waited, exit 0)", files: &[("t.csv", PLAIN)], args: &["live", "--from", "file:{d}/t.csv", "--to", "stdout", "--rate", "1e-20"], code: 2, needle: "1e-20: give 0.016666666666666666 to 10000 frames per second", absent: &[] },
    Case { name: "a take whose last row was cut short reads up to the row before it, with a warning", files: &[("cut.csv", "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0,2,0,0,1\n2,0,0,1")], args: &["info", "{d}/cut.csv"], code: 0, needle: "cut.csv: line 4, the last, is cut short", absent: &[] },
    Case { name: "a short row that is not the last is still ragged", files: &[("mid.csv", "frame,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,0,1\n1,0,0\n2,0,0,1,0,0,2")], args: &["info", "{d}/mid.csv"], code: 1, needle: "mid.csv:3:4: ragged row", absent: &[] },
    Case { name: "solve --json --png - (was: the JSON after the PNG's IEND)", files: &[], args: &["solve", "--keys", "3,40", "--json", "--png", "-"], code: 1, needle: "-: named as an output on standard output, where --json prints", absent: &[] },
    Case { name: "rig --json --gltf -", files: &[], args: &["rig", "--json", "--gltf", "-"], code: 1, needle: "where --json prints", absent: &[] },
    Case { name: "transfer --json --gltf -", files: &[], args: &["transfer", "--mesh", "{shared}/ict_facekit_face/neutral_face.obj", "--json", "--gltf", "-"], code: 1, needle: "where --json prints", absent: &[] },
    Case { name: "retarget --json --apng -", files: &[], args: &["retarget", "--json", "--apng", "-"], code: 1, needle: "where --json prints", absent: &[] },
    Case { name: "modes --json --png -", files: &[], args: &["modes", "{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--actions", "assets/actions/actions_liveportrait_d6.json", "--json", "--png", "/dev/stdout"], code: 1, needle: "where --json prints", absent: &[] },
    Case { name: "curves --png - (was: a file named -_nnls.png)", files: &[], args: &["curves", "--methods", "spread", "--k", "2..3", "--png", "-"], code: 1, needle: "--png -: names one file per solver", absent: &["-_nnls.png"] },
    Case { name: "bench nnls --frames 2^61 (was: capacity overflow)", files: &[], args: &["bench", "nnls", "--frames", "2305843009213693952"], code: 2, needle: "give 1 to 1000000 frames", absent: &[] },
    Case { name: "bench scale --frames 10^9 (was: unbounded, 13 GB of staging)", files: &[], args: &["bench", "scale", "--frames", "1000000000"], code: 2, needle: "give 1 to 1000000 frames", absent: &[] },
    Case { name: "intensity --degree 50 (was: the degree-5 result)", files: &[], args: &["intensity", "--degree", "50"], code: 1, needle: "--degree 50: give 0 to 12", absent: &[] },
    // ---- outputs as one set ----
    Case { name: "two outputs, one file spelled two ways", files: &[], args: &["curves", "--methods", "spread", "--k", "2..3", "--out", "{d}/c.csv", "--png", "{d}/./c.csv"], code: 1, needle: "c.csv: named as two outputs", absent: &["c.csv"] },
    Case { name: "rig --smooth-mode without --smooth", files: &[], args: &["rig", "--smooth-mode", "causal", "--out", "{d}/w.csv"], code: 1, needle: "--smooth-mode applies to the temporal prior", absent: &["w.csv"] },
    Case { name: "rig-accuracy --smooth-mode without --smooth", files: &[], args: &["rig-accuracy", "--smooth-mode", "causal", "--frames", "20", "--out", "{d}/a.csv"], code: 1, needle: "--smooth-mode applies to the temporal prior", absent: &["a.csv"] },
    Case { name: "rig-accuracy --live --smooth-mode offline", files: &[], args: &["rig-accuracy", "--live", "--smooth-mode", "offline", "--frames", "20", "--out", "{d}/a.csv"], code: 1, needle: "--smooth-mode offline solves each clip with frames still to come", absent: &["a.csv"] },
    Case { name: "rig --calibrations without --live", files: &[("c.jsonl", "")], args: &["rig", "--calibrations", "{d}/c.jsonl", "--out", "{d}/w.csv"], code: 1, needle: "--calibrations replays a live take's calibrations: it needs --live", absent: &["w.csv"] },
    Case { name: "rig --live --calibrations with --neutral", files: &[("c.jsonl", "")], args: &["rig", "--live", "--calibrations", "{d}/c.jsonl", "--neutral", "0-9", "--out", "{d}/w.csv"], code: 1, needle: "--neutral does not apply", absent: &["w.csv"] },
    Case { name: "rig --live --calibrations: not JSON", files: &[("c.jsonl", "{\"from\": 0}\n{not json\n")], args: &["rig", "--live", "--calibrations", "{d}/c.jsonl", "--out", "{d}/w.csv"], code: 1, needle: "c.jsonl: line 1, column", absent: &["w.csv"] },
    Case { name: "rig --live --calibrations: empty", files: &[("c.jsonl", "\n")], args: &["rig", "--live", "--calibrations", "{d}/c.jsonl", "--out", "{d}/w.csv"], code: 1, needle: "c.jsonl: holds no calibration", absent: &["w.csv"] },
    Case { name: "rig --live --identity none", files: &[], args: &["rig", "--live", "--identity", "none", "--out", "{d}/w.csv"], code: 1, needle: "a live solve calibrates the person's neutral: the identity cannot be none", absent: &["w.csv"] },
    Case { name: "rig --live --dims 3", files: &[], args: &["rig", "{shared}/mediapipe_face_tracks/liveportrait_d18.csv", "--live", "--dims", "3", "--out", "{d}/w.csv"], code: 1, needle: "--live solves image points", absent: &["w.csv"] },
    Case { name: "rig --live --smooth-mode offline", files: &[], args: &["rig", "--live", "--smooth", "10", "--smooth-mode", "offline", "--out", "{d}/w.csv"], code: 1, needle: "--live is causal: --smooth-mode offline", absent: &["w.csv"] },
    Case { name: "rig: the Live Link file on a device is refused before the weights", files: &[], args: &["rig", "--out", "{d}/r.csv", "--livelink", "/dev/full"], code: 1, needle: "/dev/full: is a device", absent: &["r.csv"] },
    Case { name: "live --mirror with no avatar sink", files: &[], args: &["live", "--from", "file:{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--to", "stdout", "--mirror", "--record", "{d}/take"], code: 1, needle: "--mirror applies to the avatar's sinks", absent: &["take"] },
    Case { name: "live --head-position with no vmc sink", files: &[], args: &["live", "--from", "file:{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--to", "livelink", "--head-position", "0,0.1,0", "--record", "{d}/take"], code: 1, needle: "--head-position applies to a vmc sink", absent: &["take"] },
    Case { name: "live --head-position of two numbers", files: &[], args: &["live", "--from", "file:{shared}/mediapipe_face_tracks/liveportrait_d6.csv", "--to", "vmc", "--head-position", "1,2"], code: 2, needle: "is not X,Y,Z", absent: &[] },
    Case { name: "a spec that would be its own report", files: &[("report.json", "title = \"x\"\ninput = \"builtin\"\nmethods = [\"spread\"]\nk = \"2..4\"\n")], args: &["run", "{d}/report.json", "--out", "{d}"], code: 1, needle: "refusing to write: this is the input file", absent: &["curves.csv"] },
];

#[test]
fn the_catalogue_of_bad_inputs() {
    assert!(CASES.len() >= 40, "the catalogue has {} cases", CASES.len());
    let shared_dir = shared("");
    let shared_dir = shared_dir.to_string_lossy();
    let shared_dir = shared_dir.trim_end_matches('/');
    let mut failures = Vec::new();
    for case in CASES {
        let d = tempfile::tempdir().unwrap();
        for (name, text) in case.files {
            let p = d.path().join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, text).unwrap();
        }
        let before = snapshot(d.path());
        let dir = d.path().display().to_string();
        let args: Vec<String> = case
            .args
            .iter()
            .map(|a| a.replace("{d}", &dir).replace("{shared}", shared_dir))
            .collect();
        let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let code = out.status.code().unwrap_or(-1);
        let stderr = String::from_utf8_lossy(&out.stderr);
        let mut why = Vec::new();
        if code != case.code {
            why.push(format!("exit code {code}, expected {}", case.code));
        }
        if !stderr.contains(case.needle) {
            why.push(format!("message lacks '{}'", case.needle));
        }
        if stderr.contains("panicked") {
            why.push("panicked".into());
        }
        for a in case.absent {
            if d.path().join(a).exists() {
                why.push(format!("left {a} behind"));
            }
        }
        // Inputs are untouched and nothing else (temporary files) is left.
        if snapshot(d.path()) != before {
            let extra: Vec<String> = case.absent.iter().map(|s| s.to_string()).collect();
            why.push(format!(
                "the directory changed (inputs modified or files left; absent: {extra:?})"
            ));
        }
        if !why.is_empty() {
            failures.push(format!(
                "{}: {}\n    args {:?}\n    stderr {}",
                case.name,
                why.join("; "),
                case.args,
                stderr.trim()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        CASES.len(),
        failures.join("\n")
    );
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                out.push((p.display().to_string(), Vec::new()));
                stack.push(p);
            } else {
                out.push((
                    p.display().to_string(),
                    std::fs::read(&p).unwrap_or_default(),
                ));
            }
        }
    }
    out.sort();
    out
}

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `--out` through a symbolic link writes the file the link names and keeps the link; a
/// dangling link creates its target; `-` is standard output; a device is written, not
/// replaced.
#[cfg(unix)]
#[test]
fn outputs_go_through_links_and_into_special_files() {
    use std::os::unix::fs::{symlink, FileTypeExt};
    let d = tempfile::tempdir().unwrap();
    let real = d.path().join("real.csv");
    std::fs::write(&real, "old").unwrap();
    let sub = d.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let link = sub.join("link.csv");
    symlink(&real, &link).unwrap();
    let (code, _, err) = run(&["solve", "--keys", "3,40", "--out", link.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read_to_string(&real)
        .unwrap()
        .starts_with("frame,rms,w_3,w_40\n"));
    // no temporary file left beside the link or the file
    let left: Vec<_> = std::fs::read_dir(&sub)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
    // a dangling relative link
    let dangling = d.path().join("dangling.csv");
    symlink("made.csv", &dangling).unwrap();
    let (code, _, err) = run(&["solve", "--keys", "3", "--out", dangling.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read_to_string(d.path().join("made.csv"))
        .unwrap()
        .starts_with("frame,"));
    assert!(std::fs::symlink_metadata(&dangling)
        .unwrap()
        .file_type()
        .is_symlink());
    // standard output
    let (code, out, err) = run(&["solve", "--keys", "3", "--out", "-"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.starts_with("frame,rms,w_3\n0,"), "{out}");
    assert_eq!(out.lines().count(), 217);
    // a device
    let (code, _, err) = run(&["solve", "--keys", "3", "--out", "/dev/null"]);
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
}

/// A link to the input is the input: refused, input untouched; so is a retarget that would
/// write over its own --target SVG.
#[cfg(unix)]
#[test]
fn an_output_that_is_an_input_by_another_name_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.csv");
    std::fs::write(&input, PLAIN).unwrap();
    let link = d.path().join("alias.csv");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    let (code, _, err) = run(&[
        "solve",
        input.to_str().unwrap(),
        "--keys",
        "0",
        "--out",
        link.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("refusing to write: this is the input file"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&input).unwrap(), PLAIN);
    let svg = d.path().join("t.svg");
    let (code, _, err) = run(&[
        "template",
        "--points",
        "lips",
        "--method",
        "spread",
        "--k",
        "3",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let before = std::fs::read(&svg).unwrap();
    let (code, _, err) = run(&[
        "retarget",
        "--points",
        "lips",
        "--target",
        svg.to_str().unwrap(),
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("refusing to write: this is the input file"),
        "{err}"
    );
    assert_eq!(std::fs::read(&svg).unwrap(), before);
}

/// A FIFO is refused at once instead of blocking.
#[cfg(unix)]
#[test]
fn a_fifo_input_is_refused_without_blocking() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("pipe.csv");
    let ok = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success());
    if !matches!(ok, Ok(true)) {
        panic!("mkfifo is needed for this test");
    }
    let (code, _, err) = run(&["info", fifo.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("pipe.csv: is not a regular file"), "{err}");
}

/// A gzip of several members is read whole; trailing junk is not gzip.
#[test]
fn every_member_of_a_multi_member_gzip_is_read() {
    use flate2::{write::GzEncoder, Compression};
    use std::io::Write;
    let gz = |text: &str| {
        let mut e = GzEncoder::new(Vec::new(), Compression::default());
        e.write_all(text.as_bytes()).unwrap();
        e.finish().unwrap()
    };
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("m.csv.gz");
    let mut bytes = gz("frame,x0,y0,x1,y1\n0,0,0,1,0\n1,0,0,2,0\n");
    bytes.extend(gz("2,0,0,1,1\n3,0,0,1,2\n4,0,0,3,1\n"));
    std::fs::write(&p, &bytes).unwrap();
    let (code, out, err) = run(&["info", p.to_str().unwrap(), "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["frames"], 5, "{out}");
    bytes.extend(b"trailing junk\n");
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = run(&["info", p.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("m.csv.gz: not a valid gzip file"), "{err}");
}

/// A full standard output is an error, not a panic.
#[cfg(target_os = "linux")]
#[test]
fn a_full_standard_output_is_an_error() {
    for args in [
        &["info"][..],
        &["keys", "--method", "spread", "--k", "3", "--json"][..],
        // Round three: the data on standard output named "<standard output>".
        &["solve", "--keys", "3", "--out", "-"][..],
    ] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_kslab"))
            .args(args)
            .stdout(full)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("writing to standard output: No space left"),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `--regions` names every weight column `region/w_N` (no duplicates) and keeps the
/// regions' keys apart in JSON.
#[test]
fn region_weights_are_named_by_region() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("w.csv");
    let (code, json, err) = run(&[
        "retarget",
        "--regions",
        "builtin",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let mut unique = header.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(
        unique.len(),
        header.len(),
        "duplicate columns in {header:?}"
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let keys = v["keys"].as_object().expect("keys per region");
    let mut expected = 0;
    for (region, frames) in keys {
        for f in frames.as_array().unwrap() {
            let col = format!("{region}/w_{f}");
            assert!(
                header.contains(&col.as_str()),
                "{col} missing from {header:?}"
            );
            expected += 1;
        }
    }
    assert_eq!(header.len(), 3 + expected + 4, "{header:?}"); // frame, rms ×2, weights, head pose
}

/// `--regions builtin` gives each region the k its regions file names (eyes 10, mouth 12),
/// not a k of the command line's.
#[test]
fn each_region_gets_the_k_of_its_regions_file() {
    let (code, json, err) = run(&["retarget", "--regions", "builtin", "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let keys = v["keys"].as_object().expect("keys per region");
    let count = |r: &str| keys[r].as_array().map_or(0, Vec::len);
    assert_eq!((count("eyes"), count("mouth")), (10, 12), "{keys:?}");
}

/// `retarget --target T.svg` uses the frames the template's groups stand for: a template of frames chosen by hand is retargeted on exactly those frames.
#[test]
fn a_target_template_brings_its_own_key_frames() {
    let d = tempfile::tempdir().unwrap();
    let svg = d.path().join("t.svg");
    let (code, _, err) = run(&[
        "template",
        "--points",
        "lips",
        "--keys",
        "5,90,170",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, json, err) = run(&[
        "retarget",
        "--points",
        "lips",
        "--target",
        svg.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let mut keys: Vec<i64> = v["keys"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_i64().unwrap())
        .collect();
    keys.sort_unstable();
    assert_eq!(keys, [5, 90, 170]);
    let (code, _, err) = run(&[
        "retarget",
        "--points",
        "lips",
        "--target",
        svg.to_str().unwrap(),
        "--k",
        "3",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("--k applies with --method"), "{err}");
}

/// `info --points lips` reports the lips' coordinate ranges, not the whole face's, checked against the ranges computed here from the built-in sequence.
#[test]
fn info_ranges_are_those_of_the_selected_points() {
    use keyshape_core::sequence::Layout;
    let seq = keyshape_io::builtin_sequence().unwrap();
    let idx = Layout::for_points(seq.points)
        .unwrap()
        .select("lips")
        .unwrap();
    let lips = seq.select_points(&idx).unwrap().ranges();
    let (code, out, err) = run(&["info", "--points", "lips", "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["ranges"]["x"][0].as_f64().unwrap(), lips[0].0, "{out}");
    assert_eq!(v["ranges"]["y"][1].as_f64().unwrap(), lips[1].1, "{out}");
    assert!(lips[0].0 > seq.ranges()[0].0 + 10.0);
}

/// Greedy over more frames than its Gram matrix allows used to be refused;
/// now it runs without that matrix (least squares exactly, nnls on a
/// subsample with exact errors) and the curve has every k.
#[test]
fn greedy_beyond_the_gram_limit_runs_without_the_frames_gram_matrix() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("long.csv");
    let mut text = String::from("frame,x0,y0,x1,y1,x2,y2\n");
    for f in 0..6001 {
        let a = (f as f64 * 0.01).sin();
        let b = (f as f64 * 0.037).cos();
        text.push_str(&format!("{f},0,0,{},{b},0,{}\n", 1.0 + a, 1.0 - 0.5 * a));
    }
    std::fs::write(&p, text).unwrap();
    let out = d.path().join("c.csv");
    let (code, _, err) = run(&[
        "curves",
        p.to_str().unwrap(),
        "--no-align",
        "--methods",
        "spread,greedy",
        "--solver",
        "nnls,ls",
        "--k",
        "1..3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let csv = std::fs::read_to_string(&out).unwrap();
    for solver in ["nnls", "ls"] {
        for k in 1..=3 {
            assert!(csv.contains(&format!("greedy,{solver},{k},")), "{csv}");
        }
    }
}

/// Default data paths do not depend on the current directory: `intensity` run from `/`
/// finds the news sample beside the repository, and `KSLAB_SHARED` overrides it with an
/// error naming the path tried.
#[test]
fn default_data_paths_do_not_depend_on_the_current_directory() {
    let bin = env!("CARGO_BIN_EXE_kslab");
    let out = Command::new(bin)
        .args(["intensity", "--json"])
        .current_dir("/")
        .env_remove("KSLAB_SHARED")
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["file"]
        .as_str()
        .unwrap()
        .ends_with("pyfeat_samples/news_sample_compact.csv"));
    let out = Command::new(bin)
        .args(["intensity"])
        .current_dir("/")
        .env("KSLAB_SHARED", "/nonexistent-kslab")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        err.contains("/nonexistent-kslab/data/pyfeat_samples/news_sample_compact.csv not found"),
        "{err}"
    );
}

/// `--head-motion` decides once for every output: with `apply` the CSV
/// carries the per-frame pose and the pictures differ from `none`; the relative motion for
/// a target with its own points rotates and scales about the target's centre.
#[test]
fn head_motion_is_one_choice_for_every_output() {
    let d = tempfile::tempdir().unwrap();
    let (a, n) = (d.path().join("a.csv"), d.path().join("n.csv"));
    let (pa, pn) = (d.path().join("a.png"), d.path().join("n.png"));
    for (csv, png, mode) in [(&a, &pa, "apply"), (&n, &pn, "none")] {
        let (code, _, err) = run(&[
            "retarget",
            "--points",
            "lips",
            "--k",
            "4",
            "--head-motion",
            mode,
            "--out",
            csv.to_str().unwrap(),
            "--apng",
            png.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
    }
    let (a, n) = (
        std::fs::read_to_string(a).unwrap(),
        std::fs::read_to_string(n).unwrap(),
    );
    assert!(a
        .lines()
        .next()
        .unwrap()
        .ends_with(",head_scale,head_angle_deg,head_tx,head_ty"));
    assert!(!n.lines().next().unwrap().contains("head_"));
    // the weights are the same either way: head motion is not part of the solve
    let strip = |t: &str| -> Vec<String> {
        t.lines()
            .map(|l| l.split(',').take(7).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(strip(&a), strip(&n));
    assert_ne!(std::fs::read(&pa).unwrap(), std::fs::read(&pn).unwrap());

    use keyshape_core::align::Similarity;
    use keyshape_retarget::with_relative_head_motion;
    use nalgebra::DMatrix;
    // a unit square in a target's own coordinates, two frames
    let sq = [0.0, 0.0, 2.0, 0.0, 2.0, 2.0, 0.0, 2.0];
    let shapes = DMatrix::from_fn(8, 2, |i, _| sq[i]);
    let head = [
        Similarity {
            scale: 2.0,
            angle: 0.3,
            t: [10.0, 5.0, 0.0],
        },
        Similarity {
            scale: 4.0,
            angle: 0.3 + std::f64::consts::FRAC_PI_2,
            t: [14.0, 5.0, 0.0],
        },
    ];
    let out = with_relative_head_motion(&shapes, &head, 2, 0.5).unwrap();
    // frame 0: the reference, unchanged
    for i in 0..8 {
        assert!((out[(i, 0)] - sq[i]).abs() < 1e-12);
    }
    // frame 1: ×2 and +90° about the centre (1, 1), then moved by 0.5 × (4, 0) / 2 = (1, 0)
    let want = [3.0, -1.0, 3.0, 3.0, -1.0, 3.0, -1.0, -1.0];
    for i in 0..8 {
        let w = want[i] + if i % 2 == 0 { 1.0 } else { 0.0 };
        assert!(
            (out[(i, 1)] - w).abs() < 1e-12,
            "coord {i}: {} vs {w}",
            out[(i, 1)]
        );
    }
}

/// Every subcommand's usage shows the input as optional `[FILE]` (the
/// built-in sequence), and every option that takes a value either is required (it is in the
/// usage line) or says its default.
#[test]
fn every_option_states_its_default_and_file_is_optional() {
    let commands = [
        "tui",
        "info",
        "solve",
        "keys",
        "curves",
        "template",
        "retarget",
        "transfer",
        "modes",
        "map",
        "intensity",
        "smooth",
    ];
    let mut missing = Vec::new();
    for c in commands {
        let (code, help, _) = run(&[c, "--help"]);
        assert_eq!(code, 0, "{c}");
        let usage = help.lines().find(|l| l.starts_with("Usage:")).unwrap();
        assert!(usage.ends_with("[FILE]"), "{c}: {usage}");
        // Option blocks: from a line starting with `-x, --name` or `--name` to the next.
        let mut blocks: Vec<String> = Vec::new();
        for line in help.lines() {
            let t = line.trim_start();
            if t.starts_with("--") || (t.starts_with('-') && t.get(2..4) == Some(", ")) {
                blocks.push(t.to_string());
            } else if let Some(b) = blocks.last_mut() {
                b.push(' ');
                b.push_str(t);
            }
        }
        for b in blocks {
            let head = b.split_whitespace().find(|w| w.starts_with("--")).unwrap();
            let takes_value = b.contains(" <");
            let required = usage.contains(&format!("{head} <"));
            if takes_value && !required && !b.to_lowercase().contains("default") {
                missing.push(format!("{c} {head}"));
            }
        }
    }
    assert!(missing.is_empty(), "no default stated: {missing:?}");
}
