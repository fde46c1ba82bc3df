//! Bidirectional texture functions (seed 000): six-dimensional textures
//! addressed by (u, v, θc, φc, θl, φl).
//!
//! * [`grid`]: the angular sampling (θ list, φ count);
//! * [`dataset`]: the codebook of images, one per (view, light) direction;
//! * [`frames`]: per-pixel angles from P, N, U, V and the camera/light;
//! * [`layout`]: the codebook layouts (a)–(f) of Fig. 4 and their filtered reads;
//! * [`synth`]: procedural BTFs rendered from height-field micro-geometry;
//! * [`features`]: the appearance features (principal components) of the sample's texels;
//! * [`index`]: index maps grown from the sample by texture synthesis;
//! * [`seams`]: how seamlessly an index map tiles;
//! * [`mip`]: MIP pyramids of index maps with per-level codebooks;
//! * [`pca`]: local PCA compression of the codebook (per-cluster bases);
//! * [`cache`]: the texture-cache model behind the paper's load efficiency.

pub mod cache;
pub mod dataset;
pub mod features;
pub mod frames;
pub mod grid;
pub mod index;
pub mod layout;
pub mod mip;
pub mod pca;
pub mod seams;
pub mod synth;

pub use dataset::Btf;
pub use frames::angles;
pub use grid::{AngularGrid, AxisLerp};
pub use layout::{AngleLerps, Codebook, Layout};
