//! The NURBS display modes: names, shader indices, flags and overlay colours.

/// What the NURBS fragment program shows. Its names ([`NurbsMode::name`])
/// are those of the command line (with the `clap` feature, `clap::ValueEnum`
/// derives the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum NurbsMode {
    /// Lit surface (Blinn–Phong) with the exact normal.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "Lit surface."))]
    Shaded,
    /// Isophotes: bands of equal angle between normal and light.
    #[cfg_attr(feature = "clap", value(help = "Isophote bands."))]
    Isophote,
    /// Reflection lines of a striped environment.
    #[cfg_attr(feature = "clap", value(help = "Reflection lines."))]
    Zebra,
    /// Highlight lines: where the normal line meets a plane of parallel
    /// light lines (view-independent, Beier & Chen).
    #[cfg_attr(feature = "clap", value(help = "Highlight lines."))]
    Highlight,
    /// Gaussian curvature on a diverging colour ramp.
    #[cfg_attr(feature = "clap", value(help = "Gaussian curvature."))]
    Gauss,
    /// Mean curvature on a diverging colour ramp.
    #[cfg_attr(feature = "clap", value(help = "Mean curvature."))]
    Mean,
    /// Isophotes of normals interpolated from the tessellation's vertices
    /// (per-vertex evaluation, the paper's Fig. 4 comparison).
    #[cfg_attr(
        feature = "clap",
        value(help = "Isophotes of interpolated vertex normals (the paper's Fig. 4 comparison).")
    )]
    VertexNormals,
    /// The exact normal as RGB.
    #[cfg_attr(feature = "clap", value(help = "Normals as RGB."))]
    Normal,
    /// Draft angle against a pull direction in three classes: positive
    /// beyond the tolerance, within it, negative beyond it.
    #[cfg_attr(
        feature = "clap",
        value(help = "Draft angle against the pull direction: positive, within tolerance, negative.")
    )]
    Draft,
    /// Where a ball tool of a given radius cannot reach: concave with a
    /// radius of curvature below it, concave above it, convex or flat.
    #[cfg_attr(
        feature = "clap",
        value(help = "Where a ball tool of radius --min-radius cannot reach (concave, tighter than it).")
    )]
    Radius,
    /// The larger principal curvature κ1 on a diverging colour ramp (signed
    /// towards the normal that faces the viewer, as the mean curvature).
    #[cfg_attr(feature = "clap", value(help = "The larger principal curvature κ1."))]
    K1,
    /// The smaller principal curvature κ2, same ramp and sign.
    #[cfg_attr(feature = "clap", value(help = "The smaller principal curvature κ2."))]
    K2,
    /// A mirror reflecting a procedural photo studio (soft boxes behind
    /// and above the viewer, one at the side, a dark floor): the
    /// highlights a class-A surface is judged by, from the exact normal.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "A mirror in a procedural photo studio (soft boxes behind and above the viewer): highlights as a class-A surfacer judges them."
        )
    )]
    Reflection,
    /// Signed deviation from a reference mesh or point cloud
    /// ([`PreparedNurbs::set_deviation`](crate::nurbs::PreparedNurbs::set_deviation)): green within the tolerance,
    /// yellow to red outside the surface, cyan to blue inside, grey where
    /// the reference has nothing near.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Signed deviation from --reference (a scan's mesh or points): green within --tolerance, yellow to red outside the surface, cyan to blue inside."
        )
    )]
    Deviation,
}

impl NurbsMode {
    /// The mode of a CLI or scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }

    /// Every mode with its CLI name.
    pub const ALL: [(&'static str, NurbsMode); 14] = [
        ("shaded", NurbsMode::Shaded),
        ("isophote", NurbsMode::Isophote),
        ("zebra", NurbsMode::Zebra),
        ("highlight", NurbsMode::Highlight),
        ("gauss", NurbsMode::Gauss),
        ("mean", NurbsMode::Mean),
        ("vertex-normals", NurbsMode::VertexNormals),
        ("normal", NurbsMode::Normal),
        ("draft", NurbsMode::Draft),
        ("radius", NurbsMode::Radius),
        ("k1", NurbsMode::K1),
        ("k2", NurbsMode::K2),
        ("deviation", NurbsMode::Deviation),
        ("reflection", NurbsMode::Reflection),
    ];
    /// The CLI and scene-file name of the mode.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(_, m)| *m == self).map_or("shaded", |(n, _)| n)
    }

    /// Index used by both fragment programs ([`mode_index`]).
    pub const fn index(self) -> u32 {
        use mode_index::*;
        match self {
            NurbsMode::Shaded => SHADED,
            NurbsMode::Isophote => ISOPHOTE,
            NurbsMode::Zebra => ZEBRA,
            NurbsMode::Gauss => GAUSS,
            NurbsMode::Mean => MEAN,
            NurbsMode::VertexNormals => VERTEX_NORMALS,
            NurbsMode::Normal => NORMAL,
            NurbsMode::Highlight => HIGHLIGHT,
            NurbsMode::Draft => DRAFT,
            NurbsMode::Radius => RADIUS,
            NurbsMode::K1 => K1,
            NurbsMode::K2 => K2,
            NurbsMode::Deviation => DEVIATION,
            NurbsMode::Reflection => REFLECTION,
        }
    }
}

/// The display modes' indices in the uniform (`params.x`), one table for
/// both programs: `cpu/nurbs.rs` matches on these, `nurbs.wgsl` on the
/// `MODE_*` constants generated from them ([`wgsl_mode_constants`]).
pub mod mode_index {
    #![allow(missing_docs)]
    pub const SHADED: u32 = 0;
    pub const ISOPHOTE: u32 = 1;
    pub const ZEBRA: u32 = 2;
    pub const GAUSS: u32 = 3;
    pub const MEAN: u32 = 4;
    pub const VERTEX_NORMALS: u32 = 5;
    pub const NORMAL: u32 = 6;
    pub const HIGHLIGHT: u32 = 7;
    pub const DRAFT: u32 = 8;
    pub const RADIUS: u32 = 9;
    pub const K1: u32 = 10;
    pub const K2: u32 = 11;
    pub const DEVIATION: u32 = 12;
    pub const REFLECTION: u32 = 13;
}

/// Bits of the flags word (`params.w`) of [`NurbsFrame`](crate::nurbs::NurbsFrame).
pub mod flag {
    /// Prepared-degree kernels.
    pub const PREPARED: u32 = 1;
    /// Patch-boundary overlay.
    pub const BOUNDARIES: u32 = 2;
    /// Isoparametric lines overlay (`lines.w` per patch and direction).
    pub const ISOLINES: u32 = 4;
    /// Section curves of a plane family (`lines.xyz` = normal / spacing).
    pub const SECTIONS: u32 = 8;
    /// Classified edges ([`PackedNurbs::edges`](crate::nurbs::PackedNurbs::edges)).
    pub const EDGES: u32 = 16;
}

/// Overlay colours (sRGB bytes): isoparametric lines and section curves.
pub const ISOLINE_RGB: [u8; 3] = [64, 70, 82];
/// See [`ISOLINE_RGB`].
pub const SECTION_RGB: [u8; 3] = [200, 40, 200];

/// WGSL constants `MODE_<NAME>` for every display mode (the CLI name in
/// capitals, `-` as `_`) and the overlay colours `ISOLINE_RGB`,
/// `SECTION_RGB`, prepended to `nurbs.wgsl`.
pub fn wgsl_mode_constants() -> String {
    let rgb = |c: [u8; 3]| format!("vec3<f32>({}.0 / 255.0, {}.0 / 255.0, {}.0 / 255.0)", c[0], c[1], c[2]);
    let mut s: String = NurbsMode::ALL
        .iter()
        .map(|(name, m)| format!("const MODE_{}: u32 = {}u;\n", name.to_ascii_uppercase().replace('-', "_"), m.index()))
        .collect();
    s += &format!("const ISOLINE_RGB: vec3<f32> = {};\n", rgb(ISOLINE_RGB));
    s += &format!("const SECTION_RGB: vec3<f32> = {};\n", rgb(SECTION_RGB));
    s
}
