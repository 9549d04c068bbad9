//! Readers and writers. Every reader returns a validated [`Sequence`](keyshape_core::Sequence); every error names the
//! file and, for parse errors, the line and column.
//!
//! **The front door:** [`read_sequence`] with [`ReadOptions`] (any track kslab reads, format
//! detected) and [`builtin_sequence`]; [`write_atomic`] (a file appears whole or not at
//! all) and [`OutputSet`] (several files, all or none); [`csv_out`] for tables. The modules
//! hold the rest: meshes ([`obj`]), morph targets ([`morph`]), GLB ([`gltf`]), JSON tracks,
//! synthetic long tracks for benchmarks, and the solve of a track of any length streamed
//! from its file to its weights ([`stream`]).
//!
//! A whole solve, from the built-in sequence to blend weights:
//!
//! ```
//! use keyshape_core::{decompose, prepare, PrepareOptions, SolveOptions, Solver};
//! use keyshape_io::builtin_sequence;
//!
//! let seq = builtin_sequence()?;
//! let opts = PrepareOptions::group_aligned("lips");
//! let prep = prepare(&seq, &opts)?;
//! let keys: Vec<usize> = [0, 60, 120, 180, 215]
//!     .iter()
//!     .map(|&f| prep.seq.column_of_frame(f))
//!     .collect::<Result<_, _>>()?;
//! let nnls = SolveOptions::new(Solver::Nnls);
//! let d = decompose(&prep, &keys, None, &nnls)?;
//! assert_eq!(d.negative_share(), 0.0);
//! assert!(d.mean_rms() < 5.0); // pixels
//! # Ok::<(), keyshape_core::Error>(())
//! ```

pub mod atomic;
mod builtin;
pub mod csv_error;
pub mod csv_out;
pub mod gltf;
pub mod json;
pub mod morph;
pub mod obj;
mod pts;

mod line_index;
mod read;
mod shared;
pub mod stream;
pub mod synthetic;
pub mod table;
mod text;

pub use atomic::{check_output, check_output_dir, create_dir_all, write_atomic, OutputSet};
pub use builtin::{builtin_json, builtin_sequence, BUILTIN_NAME};
pub use csv_out::fmt_num;
pub use read::{detect_format, open_input, parse_sequence, read_sequence, ReadOptions};
pub use shared::shared_data;
pub use text::{
    read_bytes, read_columns, read_json, read_line_capped, read_text, text_from_bytes, Line,
    MAX_INPUT_BYTES, MAX_LINE_BYTES,
};
