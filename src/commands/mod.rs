//! The bodies of `voxlab`'s larger commands, one module each (`main.rs` keeps the
//! argument types the commands share and the dispatch).

pub(crate) mod ablate;
pub(crate) mod bench;
pub(crate) mod export;
pub(crate) mod mesh;
pub(crate) mod stress;
