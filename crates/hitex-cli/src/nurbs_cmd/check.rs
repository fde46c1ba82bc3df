//! `hitex nurbs check`: continuity across the edges that faces share, and
//! the continuity display mode that draws the same edges on the model.

use super::*;

/// Arguments of `hitex nurbs check`.
#[derive(Args)]
pub struct CheckArgs {
    /// Model name or file.
    pub model: String,
    /// STEP: largest distance between a trim as drawn and the true edge,
    /// model units (default: 1/10 000 of the model's size).
    #[arg(long, allow_negative_numbers = true)]
    pub chord: Option<f64>,
    /// Largest gap allowed, model units (default: 1e-4 of the model's bounding diagonal).
    #[arg(long, allow_negative_numbers = true)]
    pub g0: Option<f64>,
    /// Largest angle between the normals across an edge, degrees (gates only when given;
    /// 1° classifies otherwise).
    #[arg(long, allow_negative_numbers = true)]
    pub g1: Option<f64>,
    /// Largest relative jump of the normal curvature across an edge (gates only when
    /// given; 0.1 classifies otherwise).
    #[arg(long, allow_negative_numbers = true)]
    pub g2: Option<f64>,
    /// Sample spacing along the edges, model units (default: 1/500 of the bounding diagonal).
    #[arg(long, allow_negative_numbers = true)]
    pub spacing: Option<f64>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// The continuity an edge reaches under the tolerances.
fn edge_class(e: &hitex_core::nurbs::continuity::Edge, g0: f64, g1: f64, g2: f64) -> &'static str {
    match e.neighbour {
        None => "naked",
        Some(_) if e.g0.value > g0 => "gap",
        Some(_) if e.g1_deg.value > g1 => "G0",
        Some(_) if e.g2_rel.value > g2 => "G1",
        Some(_) => "G2",
    }
}

/// Most boundary samples `nurbs check` takes (about 200 bytes each while
/// the edges are matched).
const MAX_CHECK_SAMPLES: u64 = 4_000_000;

/// The edges of a model found and measured as `nurbs check` does.
pub struct FoundEdges {
    /// Every edge, shared ones once.
    pub edges: Vec<hitex_core::nurbs::continuity::Edge>,
    /// The model's size (its control nets' bounding diagonal).
    pub size: f64,
    /// The largest gap allowed (model units).
    pub g0: f64,
    /// Sample spacing along the edges.
    pub spacing: f64,
    /// Sampling and matching settings.
    pub opts: hitex_core::nurbs::continuity::CheckOptions,
    /// Time taken.
    pub ms: f64,
}

/// Finds and measures the edges of `m` (`g0`, `spacing`: as given, else
/// 1e-4 and 1/500 of the model's bounding diagonal), refusing a spacing
/// whose samples would not fit [`MAX_CHECK_SAMPLES`].
pub fn find_edges(m: &NurbsModel, g0: Option<f64>, spacing: Option<f64>) -> Result<FoundEdges, CliError> {
    use hitex_core::nurbs::continuity::{CheckOptions, Face, check_with_progress, sample_count};
    // the model's size: the diagonal of its control nets' bounds
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for s in &m.surfaces {
        let (a, b) = s.surface.bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let size = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt().max(1e-300);
    let g0 = g0.unwrap_or(1e-4 * size);
    let spacing = spacing.unwrap_or(size / 500.0);
    let opts = CheckOptions { spacing, match_radius: (2.0 * g0).max(2e-3 * size) };
    let faces: Vec<Face> =
        m.surfaces.iter().map(|s| Face { surface: &s.surface, range: s.range, loops: &s.trim }).collect();
    // the work grows with the boundary samples: counted and bounded first
    let samples = sample_count(&faces, spacing);
    if samples > MAX_CHECK_SAMPLES {
        let finest = spacing * samples as f64 / MAX_CHECK_SAMPLES as f64;
        return Err(CliError::Input(format!(
            "--spacing {}: {} would take {samples} boundary samples (at most {MAX_CHECK_SAMPLES}); \
             give --spacing {} or more",
            fmt(spacing),
            m.name,
            fmt(finest * 1.01)
        )));
    }
    let t = Instant::now();
    let bar = crate::progress::Progress::new(
        faces.len() as u64,
        "check",
        "faces",
        "{prefix:>12} [{bar:30}] {pos}/{len} faces {elapsed}",
    );
    let edges = check_with_progress(&faces, &opts, size, &|| bar.inc(1));
    bar.finish_and_clear();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    Ok(FoundEdges { edges, size, g0, spacing, opts, ms })
}

/// Refuses continuity tolerances (and a spacing) that are not finite and
/// positive, and a G1 angle of 180° or more (normals meet at 180° at most: it
/// would gate nothing).
fn check_tolerances(g0: Option<f64>, g1: Option<f64>, g2: Option<f64>, spacing: Option<f64>) -> Result<(), CliError> {
    for (name, v) in [("--g0", g0), ("--g1", g1), ("--g2", g2), ("--spacing", spacing)] {
        if let Some(x) = v
            && !(x.is_finite() && x > 0.0)
        {
            return Err(CliError::Input(format!("{name} {x} must be finite and positive")));
        }
    }
    if let Some(t) = g1
        && t >= 180.0
    {
        return Err(CliError::Input(format!("--g1 {t} must be below 180 degrees")));
    }
    Ok(())
}

pub(super) fn check(a: CheckArgs) -> Result<(), CliError> {
    check_tolerances(a.g0, a.g1, a.g2, a.spacing)?;
    let m = load(&a.model, a.chord)?;
    for w in &m.warnings {
        eprintln!("hitex: warning: {}: {w}", m.name);
    }
    if m.surfaces.is_empty() {
        return Err(CliError::Input(format!("{}: no surfaces to check", m.name)));
    }
    let found = find_edges(&m, a.g0, a.spacing)?;
    let FoundEdges { edges, size, g0, spacing, opts, ms } = found;
    let (g1, g2) = (a.g1.unwrap_or(1.0), a.g2.unwrap_or(0.1));
    let shared: Vec<_> = edges.iter().filter(|e| e.neighbour.is_some()).collect();
    let naked: Vec<_> = edges.iter().filter(|e| e.neighbour.is_none()).collect();
    let failed: Vec<_> = shared
        .iter()
        .filter(|e| {
            e.g0.value > g0 || a.g1.is_some_and(|t| e.g1_deg.value > t) || a.g2.is_some_and(|t| e.g2_rel.value > t)
        })
        .collect();
    let de = |i: usize| m.surfaces[i].directory_entry;
    // faces lying on each other over an area, within the gap tolerance
    let faces: Vec<hitex_core::nurbs::continuity::Face> = m
        .surfaces
        .iter()
        .map(|s| hitex_core::nurbs::continuity::Face { surface: &s.surface, range: s.range, loops: &s.trim })
        .collect();
    let overlaps = hitex_core::nurbs::continuity::overlaps(&faces, g0, 8);
    let non_manifold: Vec<_> = shared.iter().filter(|e| !e.also.is_empty()).collect();
    if a.json {
        let rows: Vec<_> = edges
            .iter()
            .map(|e| {
                serde_json::json!({
                    "face": e.face, "face_de": de(e.face),
                    "neighbour": e.neighbour, "neighbour_de": e.neighbour.map(de),
                    "samples": e.samples, "length": e.length,
                    "g0": e.g0, "g1_deg": e.g1_deg, "g2_rel": e.g2_rel,
                    "class": edge_class(e, g0, g1, g2),
                    "also": e.also,
                })
            })
            .collect();
        let v = serde_json::json!({
            "model": m.name, "faces": m.surfaces.len(), "size": size,
            "tolerances": {"g0": g0, "g1_deg": a.g1, "g2_rel": a.g2},
            "classify": {"g0": g0, "g1_deg": g1, "g2_rel": g2},
            "spacing": spacing, "match_radius": opts.match_radius,
            "shared_edges": shared.len(), "naked_edges": naked.len(), "failed": failed.len(),
            "edges": rows,
            "non_manifold_edges": non_manifold.len(),
            "overlaps": overlaps,
        });
        say!("{}", serde_json::to_string_pretty(&v).map_err(|e| CliError::Internal(e.to_string()))?);
    } else {
        let naked_len: f64 = naked.iter().map(|e| e.length).sum();
        say!(
            "{}: {} (numbered as --patch counts), {} shared, {} naked (length {}); sampled every {}, matched within {} ({ms:.0} ms)",
            m.name,
            crate::count(m.surfaces.len(), "face", "faces"),
            crate::count(shared.len(), "edge", "edges"),
            crate::count(naked.len(), "edge", "edges"),
            fmt(naked_len),
            fmt(spacing),
            fmt(opts.match_radius),
        );
        say!(
            "classes: G2 within |Δκ|/κ ≤ {g2}, G1 within {g1}°, G0 within gap ≤ {}; \
             G1/G2 gate only when --g1/--g2 are given",
            fmt(g0)
        );
        say!(
            "{:>14}  {:>10} {:>6}  {:>10} {:>8} {:>8}  {:<5}  worst at",
            "faces",
            "length",
            "samples",
            "G0 gap",
            "G1 deg",
            "G2 rel",
            "class"
        );
        for e in &edges {
            let pair = match e.neighbour {
                Some(b) => format!("{}–{}", e.face, b),
                None => format!("{}", e.face),
            };
            let class = edge_class(e, g0, g1, g2);
            // where the figure that decides the class peaks
            let at = match class {
                "gap" | "G2" => e.g0.at,
                "G0" => e.g1_deg.at,
                "G1" => e.g2_rel.at,
                _ => [f64::NAN; 3],
            };
            let at = if e.neighbour.is_some() {
                format!("({}, {}, {})", fmt(at[0]), fmt(at[1]), fmt(at[2]))
            } else {
                String::new()
            };
            say!(
                "{pair:>14}  {:>10} {:>6}  {:>10} {:>8.3} {:>8.3}  {class:<5}  {at}",
                fmt(e.length),
                e.samples,
                fmt(e.g0.value),
                e.g1_deg.value,
                e.g2_rel.value
            );
        }
        if !non_manifold.is_empty() {
            say!(
                "{} shared by three faces or more (a solid's boundary has none; in an assembly, parts in contact):",
                crate::count(non_manifold.len(), "edge", "edges")
            );
            for e in &non_manifold {
                let also: Vec<String> = e.also.iter().map(usize::to_string).collect();
                say!("  {}–{} also meets face {}", e.face, e.neighbour.unwrap_or(e.face), also.join(", "));
            }
        }
        if overlaps.is_empty() {
            say!("no faces lie on each other (interiors sampled 8×8 per face, within the gap tolerance)");
        } else {
            say!(
                "{} lying on each other (faces given twice; in an assembly, parts in contact):",
                crate::count(overlaps.len(), "pair of faces", "pairs of faces")
            );
            for o in &overlaps {
                say!(
                    "  {}–{}: {:.0} % of face {}'s interior samples, e.g. at ({}, {}, {})",
                    o.face,
                    o.other,
                    100.0 * o.fraction,
                    o.face,
                    fmt(o.at[0]),
                    fmt(o.at[1]),
                    fmt(o.at[2])
                );
            }
        }
    }
    if !failed.is_empty() {
        return Err(CliError::Check(format!(
            "{}: {} of {} exceed the tolerances",
            m.name,
            crate::count(failed.len(), "shared edge", "shared edges"),
            shared.len()
        )));
    }
    Ok(())
}

/// The classes `nurbs check` gives an edge, with the colour `--continuity`
/// draws them in and their legend label.
pub const CONTINUITY_CLASSES: [(&str, [u8; 3], &str); 5] = [
    ("G2", [60, 200, 90], "G2"),
    ("G1", [245, 225, 60], "G1"),
    ("G0", [255, 140, 20], "G0 CREASE"),
    ("gap", [235, 35, 35], "GAP"),
    ("naked", [230, 50, 220], "NAKED"),
];

/// Finds the model's edges as `nurbs check` does and gives `p` each one's
/// path on both its faces, coloured by its class; returns the report line.
pub fn set_up_continuity(
    p: &mut PreparedNurbs,
    model: &NurbsModel,
    g0: Option<f64>,
    g1: Option<f64>,
    g2: Option<f64>,
) -> Result<String, CliError> {
    check_tolerances(g0, g1, g2, None)?;
    if model.surfaces.is_empty() {
        return Ok("continuity: no surfaces".into());
    }
    let found = find_edges(model, g0, None)?;
    let (g1, g2) = (g1.unwrap_or(1.0), g2.unwrap_or(0.1));
    let mut runs: Vec<Vec<hitex_render::nurbs::EdgeRun>> = vec![Vec::new(); p.surfaces.len()];
    let mut counts = [0usize; 5];
    for e in &found.edges {
        let class = edge_class(e, found.g0, g1, g2);
        let k = CONTINUITY_CLASSES.iter().position(|c| c.0 == class).unwrap_or(4);
        counts[k] += 1;
        let rgb = CONTINUITY_CLASSES[k].1;
        if let Some(r) = runs.get_mut(e.face) {
            r.push((e.path.clone(), rgb));
        }
        if let Some(b) = e.neighbour
            && let Some(r) = runs.get_mut(b)
        {
            r.push((e.neighbour_path.clone(), rgb));
        }
    }
    p.set_edges(&runs);
    let names = ["green", "yellow", "orange", "red", "magenta"];
    let parts: Vec<String> = CONTINUITY_CLASSES
        .iter()
        .zip(counts)
        .zip(names)
        .filter(|((_, n), _)| *n > 0)
        .map(|((c, n), colour)| format!("{n} {} ({colour})", c.0))
        .collect();
    Ok(format!(
        "continuity: {} ({}), found as `nurbs check` finds them in {:.0} ms: gap beyond {}, G1 within {g1}°, \
         G2 within {g2} relative curvature jump",
        crate::count(found.edges.len(), "edge", "edges"),
        parts.join(", "),
        found.ms,
        fmt(found.g0)
    ))
}
