//! The revision voxlab was built from: `git rev-parse HEAD` when `build.rs` ran, with
//! `-dirty` when the sources that make the binary (`src`, `shaders`, the manifests)
//! differed from it, "unknown" without git. Read at build time, so a binary names its
//! own code after the checkout has moved on.

/// The build's revision (see the module documentation).
pub fn revision() -> &'static str {
    env!("VOXLAB_REVISION")
}
