//! A model's parts (patches, their parameter ranges, trimming loops and
//! face colours, as `hitex_io::models::NurbsModel` holds them) prepared for
//! rendering in one step that asks for every part, so that no caller drops
//! the trims or the colours by forgetting a call.

use crate::nurbs::{ParamRange, PreparedNurbs, TrimLoops, fitted_grids};
use hitex_core::nurbs::NurbsSurface;
use std::fmt;

/// How finely the mesh that places a model's fragments is cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Density {
    /// Each patch's grid fitted to the surface ([`fitted_grids`]), at least
    /// 8 cells a side.
    Auto,
    /// An N×N grid on every patch.
    Fixed(u32),
}

/// How a model's mesh was cut ([`PreparedNurbs::from_parts`]); its
/// `Display` is the line the CLI shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeshCut {
    /// An N×N grid on every patch.
    Fixed(u32),
    /// Each patch fitted within `chord` model units of its surface along
    /// the grid lines; `cells` the fewest and most cells a patch side
    /// (`None` for a model without patches).
    Fitted {
        /// Fewest and most cells a patch side.
        cells: Option<(u32, u32)>,
        /// The largest distance between mesh and surface, model units.
        chord: f64,
    },
}

impl fmt::Display for MeshCut {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MeshCut::Fixed(n) => write!(f, "{n}×{n} cells a patch"),
            MeshCut::Fitted { cells: None, .. } => write!(f, "auto"),
            MeshCut::Fitted { cells: Some((lo, hi)), chord } => {
                // three significant digits, plainly where that stays short
                let within = if (1e-3..1e6).contains(&chord) {
                    let decimals = (2 - chord.log10().floor() as i32).max(0) as usize;
                    format!("{chord:.decimals$}")
                } else {
                    format!("{chord:.2e}")
                };
                write!(f, "auto, {lo} to {hi} cells a patch side, within {within} model units of the surface")
            }
        }
    }
}

/// The diagonal of the box around the surfaces, each sampled on a 9×9
/// grid over its range (`ranges[k]`, else its domain; control points can
/// lie far off a trimmed face); 0 when nothing finite was found.
pub fn model_size(surfaces: &[NurbsSurface], ranges: &[ParamRange]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (k, s) in surfaces.iter().enumerate() {
        let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
        for j in 0..=8 {
            for i in 0..=8 {
                let p = s.point(u0 + (u1 - u0) * i as f64 / 8.0, v0 + (v1 - v0) * j as f64 / 8.0);
                if p.iter().all(|x| x.is_finite()) {
                    for t in 0..3 {
                        lo[t] = lo[t].min(p[t]);
                        hi[t] = hi[t].max(p[t]);
                    }
                }
            }
        }
    }
    let d = (0..3).map(|t| (hi[t] - lo[t]).powi(2)).sum::<f64>().sqrt();
    if d.is_finite() { d } else { 0.0 }
}

impl PreparedNurbs {
    /// A model prepared for rendering: its patches over their parameter
    /// `ranges`, trimmed by their loops (`trims`, one list a patch; empty:
    /// untrimmed), in the faces' `colors` where given (empty: none), on the
    /// mesh `density` asks for (`Auto`: each patch fitted within
    /// `mesh_chord` model units, by default 1/4000 of [`model_size`]); with
    /// how the mesh was cut.
    pub fn from_parts(
        surfaces: Vec<NurbsSurface>,
        ranges: &[ParamRange],
        trims: &[TrimLoops],
        colors: &[Option<[f32; 3]>],
        density: Density,
        mesh_chord: Option<f64>,
    ) -> (Self, MeshCut) {
        let (mut p, cut) = match density {
            Density::Fixed(n) => (PreparedNurbs::trimmed(surfaces, ranges, trims, n), MeshCut::Fixed(n)),
            Density::Auto => {
                let chord = mesh_chord.unwrap_or_else(|| model_size(&surfaces, ranges) / 4000.0);
                let grids = fitted_grids(&surfaces, ranges, 8, chord);
                let cells = grids.iter().fold(None, |acc: Option<(u32, u32)>, &(a, b)| {
                    let (lo, hi) = acc.unwrap_or((u32::MAX, 0));
                    Some((lo.min(a.min(b)), hi.max(a.max(b))))
                });
                (PreparedNurbs::trimmed_grids(surfaces, ranges, trims, &grids), MeshCut::Fitted { cells, chord })
            }
        };
        if colors.iter().any(Option::is_some) {
            p.set_colors(colors);
        }
        (p, cut)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mesh_cut_reads_as_the_user_is_told() {
        assert_eq!(MeshCut::Fixed(8).to_string(), "8×8 cells a patch");
        assert_eq!(MeshCut::Fitted { cells: None, chord: 0.5 }.to_string(), "auto");
        let s = MeshCut::Fitted { cells: Some((8, 16)), chord: 0.066_43 }.to_string();
        assert_eq!(s, "auto, 8 to 16 cells a patch side, within 0.0664 model units of the surface");
        let s = MeshCut::Fitted { cells: Some((8, 8)), chord: 2.5e-5 }.to_string();
        assert!(s.ends_with("within 2.50e-5 model units of the surface"), "{s}");
    }

    #[test]
    fn a_model_keeps_its_trims_and_colours() {
        let model = hitex_io::models::load_model("teapot").unwrap();
        let prepare = |m: &hitex_io::models::NurbsModel, density| {
            PreparedNurbs::from_parts(m.nurbs(), &m.ranges(), &m.trims(), &m.colors, density, None)
        };
        let size = model_size(&model.nurbs(), &model.ranges());
        // the teapot is about 6.4 units long and 3.2 high
        assert!((5.0..10.0).contains(&size), "{size}");
        let (fixed, cut) = prepare(&model, Density::Fixed(4));
        assert_eq!(cut, MeshCut::Fixed(4));
        let (auto, cut) = prepare(&model, Density::Auto);
        let MeshCut::Fitted { cells: Some((lo, hi)), chord } = cut else { panic!("{cut:?}") };
        assert!(lo >= 8 && hi >= lo && (chord - size / 4000.0).abs() < 1e-12, "{cut:?}");
        assert!(auto.packed.patches == fixed.packed.patches && auto.packed.patches == model.surfaces.len() as u32);
        // a trimmed face and a coloured one: both reach the packed model
        let mut m = model.clone();
        m.surfaces.truncate(1);
        m.surfaces[0].trim = vec![vec![[0.2, 0.2], [0.8, 0.2], [0.8, 0.8], [0.2, 0.8], [0.2, 0.2]]];
        m.colors = vec![Some([1.0, 0.0, 0.0])];
        for density in [Density::Fixed(4), Density::Auto] {
            let (p, _) = prepare(&m, density);
            assert!(p.packed.trims[0][0] > 0.0, "{density:?}: the trim loop was dropped");
            assert_eq!(p.packed.colors[0], Some([1.0, 0.0, 0.0]), "{density:?}");
        }
    }
}
