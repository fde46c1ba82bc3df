//! `hitex nurbs deviation` and the deviation display mode: the exact
//! surfaces measured against a reference (points, a mesh).

use super::*;

/// Arguments of `hitex nurbs deviation`.
#[derive(Args)]
pub struct DeviationArgs {
    /// Model name or file.
    pub model: String,
    /// The points: `{"points": [[x, y, z], …]}` (.json), the vertices of a PLY file (.ply), or XYZ text (x y z a line).
    #[arg(long)]
    pub points: PathBuf,
    /// Print JSON: every distance, and max, mean, RMS with where the largest is.
    #[arg(long)]
    pub json: bool,
    /// STEP: the trims' chord tolerance, model units.
    #[arg(long, allow_negative_numbers = true)]
    pub chord: Option<f64>,
}

pub(super) fn deviation(a: DeviationArgs) -> Result<(), CliError> {
    use hitex_core::nurbs::measure::{DistanceFace, nearest_face};
    use rayon::prelude::*;
    let m = load(&a.model, a.chord)?;
    let points = hitex_io::points::load_points(&a.points)?;
    let faces: Vec<DistanceFace> = m.surfaces.iter().map(|s| DistanceFace::new(&s.surface, s.range, &s.trim)).collect();
    let t = Instant::now();
    let bar = crate::progress::Progress::new(
        points.len() as u64,
        "deviation",
        "points",
        "{prefix:>12} [{bar:30}] {pos}/{len} points {elapsed} (eta {eta})",
    );
    // the bar moves by chunks of points, not per point
    let found: Vec<(f64, usize)> = points
        .par_chunks(4096)
        .flat_map_iter(|chunk| {
            let out: Vec<(f64, usize)> =
                chunk.iter().map(|p| nearest_face(&faces, *p).map_or((f64::INFINITY, 0), |(d, i, _)| (d, i))).collect();
            bar.inc(chunk.len() as u64);
            out
        })
        .collect();
    bar.finish_and_clear();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let n = found.len() as f64;
    let mean = found.iter().map(|f| f.0).sum::<f64>() / n;
    let rms = (found.iter().map(|f| f.0 * f.0).sum::<f64>() / n).sqrt();
    let (worst, &(max, face)) = found
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.0.total_cmp(&y.1.0))
        .ok_or_else(|| CliError::Input("no points".into()))?;
    let units = m.units.clone().unwrap_or_default();
    if a.json {
        let v = serde_json::json!({
            "model": m.name, "points": found.len(), "units": units,
            "max": max, "mean": mean, "rms": rms,
            "worst": {"index": worst, "point": points[worst], "face": face, "face_de": m.surfaces.get(face).map(|s| s.directory_entry)},
            "distances": found.iter().map(|f| f.0).collect::<Vec<_>>(),
            "faces": found.iter().map(|f| f.1).collect::<Vec<_>>(),
        });
        say!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
    } else {
        let u = if units.is_empty() { String::new() } else { format!(" {units}") };
        say!("{}: {} to {} faces ({ms:.0} ms)", m.name, crate::count(found.len(), "point", "points"), m.surfaces.len());
        say!(
            "max {}{u} (point {worst} at {:?}, face {face}), mean {}{u}, RMS {}{u}",
            fmt(max),
            points[worst],
            fmt(mean),
            fmt(rms)
        );
    }
    Ok(())
}

/// How the deviation mode measures and colours (`None`: the defaults).
pub struct DeviationOptions {
    /// Grid points per face side.
    pub grid: usize,
    /// In tolerance within ± this.
    pub tolerance: Option<f32>,
    /// The colours saturate at ± this.
    pub range: Option<f32>,
    /// No data farther than this from the reference.
    pub max_distance: Option<f64>,
}

impl DeviationOptions {
    /// Refuses values out of range, naming the option.
    pub fn check(&self) -> Result<(), CliError> {
        let g = self.grid;
        if !(2..=hitex_render::nurbs::MAX_DEVIATION_GRID).contains(&g) {
            return Err(CliError::Input(format!(
                "--deviation-grid {g} must be in 2…{} points per face side",
                hitex_render::nurbs::MAX_DEVIATION_GRID
            )));
        }
        for (name, v) in [("--tolerance", self.tolerance.map(f64::from)), ("--max-distance", self.max_distance)] {
            if let Some(x) = v
                && !(x.is_finite() && x > 0.0)
            {
                return Err(CliError::Input(format!("{name} {x} must be finite and positive (model units)")));
            }
        }
        Ok(())
    }
}

/// Measures every face of `p` against `data` (named `name` in messages) on
/// a grid, for the deviation mode, and sets the colour scale; returns the
/// lines that report it.
pub fn set_up_deviation(
    p: &mut PreparedNurbs,
    model: &NurbsModel,
    data: hitex_io::stl::ReferenceData,
    name: &str,
    a: &DeviationOptions,
) -> Result<Vec<String>, CliError> {
    use hitex_core::nurbs::deviation::{NO_DATA, Reference, deviation_grid, is_no_data};
    use hitex_core::nurbs::measure::inside_loops;
    use rayon::prelude::*;
    let g = a.grid;
    // the model's size: the diagonal of its control nets' bounds
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for s in &p.surfaces {
        let (a, b) = s.bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let size = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let max = a.max_distance.unwrap_or(size / 20.0);
    let t = Instant::now();
    // one reference for every face (a mesh), or per face the cloud's points
    // measured on it (each point inverted onto its nearest face)
    let (references, what, point_stats) = match data {
        hitex_io::stl::ReferenceData::Mesh(tris) => {
            let n = tris.len();
            let r = Reference::mesh(tris);
            (vec![r; 1], crate::count(n, "triangle", "triangles"), None)
        }
        hitex_io::stl::ReferenceData::Points(pts) => {
            use hitex_core::nurbs::deviation::measure_point;
            use hitex_core::nurbs::measure::DistanceFace;
            let faces: Vec<DistanceFace> =
                model.surfaces.iter().map(|s| DistanceFace::new(&s.surface, s.range, &s.trim)).collect();
            let bar = crate::progress::Progress::new(
                pts.len() as u64,
                "measuring",
                "points",
                "{prefix:>12} [{bar:30}] {pos}/{len} points {elapsed} (eta {eta})",
            );
            let found: Vec<Option<(usize, f64)>> = pts
                .par_chunks(1024)
                .flat_map_iter(|chunk| {
                    let out: Vec<_> = chunk.iter().map(|q| measure_point(&faces, *q, max)).collect();
                    bar.inc(chunk.len() as u64);
                    out
                })
                .collect();
            bar.finish_and_clear();
            let mut per_face = vec![(Vec::new(), Vec::new()); p.surfaces.len()];
            let mut values = Vec::new();
            for (q, f) in pts.iter().zip(&found) {
                if let Some((face, d)) = f
                    && let Some(slot) = per_face.get_mut(*face)
                {
                    slot.0.push(*q);
                    slot.1.push(*d);
                    values.push(*d);
                }
            }
            let refs = per_face.iter().map(|(q, d)| Reference::measured_points(q, d)).collect();
            (refs, crate::count(pts.len(), "point", "points"), Some((values, pts.len())))
        }
    };
    let bar = crate::progress::Progress::new(
        p.surfaces.len() as u64,
        "deviation",
        "faces",
        "{prefix:>12} [{bar:30}] {pos}/{len} faces {elapsed} (eta {eta})",
    );
    let grids: Vec<Vec<f32>> = p
        .surfaces
        .par_iter()
        .enumerate()
        .map(|(k, s)| {
            let r = &references[if references.len() == 1 { 0 } else { k }];
            let v = deviation_grid(s, s.domain(), r, g, max);
            bar.inc(1);
            v
        })
        .collect();
    bar.finish_and_clear();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    // statistics over the grid points on the kept (trimmed) part of each face
    let trims = model.trims();
    let mut known: Vec<(f32, usize, usize)> = Vec::new();
    let mut kept = 0usize;
    for (k, (s, v)) in p.surfaces.iter().zip(&grids).enumerate() {
        let ((u0, u1), (v0, v1)) = s.domain();
        let loops = trims.get(k).map(Vec::as_slice).unwrap_or(&[]);
        for (idx, d) in v.iter().enumerate() {
            let (i, j) = (idx % g, idx / g);
            let uv = [u0 + (u1 - u0) * i as f64 / (g - 1) as f64, v0 + (v1 - v0) * j as f64 / (g - 1) as f64];
            if !loops.is_empty() && !inside_loops(loops, uv) {
                continue;
            }
            kept += 1;
            if !is_no_data(*d) {
                known.push((*d, k, idx));
            }
        }
    }
    if known.is_empty() {
        let (mut rlo, mut rhi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for (a, b) in references.iter().filter_map(Reference::bounds) {
            for k in 0..3 {
                rlo[k] = rlo[k].min(a[k]);
                rhi[k] = rhi[k].max(b[k]);
            }
        }
        return Err(CliError::Input(format!(
            "{name}: no point of the reference ({what}, bounds {} … {}) lies within {} of the surface (bounds {} … {}): \
             check that both are in the same units and place, or raise --max-distance",
            xyz(rlo),
            xyz(rhi),
            fmt(max),
            xyz(lo),
            xyz(hi)
        )));
    }
    // the scale from the cloud's own points where it is one, else the grid's
    let mut mags: Vec<f32> = match &point_stats {
        Some((v, _)) if !v.is_empty() => v.iter().map(|x| x.abs() as f32).collect(),
        _ => known.iter().map(|x| x.0.abs()).collect(),
    };
    mags.sort_by(f32::total_cmp);
    let p99 = mags[((mags.len() - 1) as f64 * 0.99).round() as usize] as f64;
    let range = match a.range {
        Some(r) => r,
        None => nice_up(p99.max(size * 1e-7)) as f32,
    };
    let tol = a.tolerance.unwrap_or(range / 5.0);
    p.deviation_range = (tol, range);
    p.set_deviation(g, &grids);
    let n = known.len() as f64;
    let mean = known.iter().map(|x| x.0 as f64).sum::<f64>() / n;
    let rms = (known.iter().map(|x| (x.0 as f64).powi(2)).sum::<f64>() / n).sqrt();
    let within = known.iter().filter(|x| x.0.abs() <= tol).count() as f64 / n * 100.0;
    let at = |x: &(f32, usize, usize)| {
        let s = &p.surfaces[x.1];
        let ((u0, u1), (v0, v1)) = s.domain();
        let (i, j) = (x.2 % g, x.2 / g);
        let q = s.point(u0 + (u1 - u0) * i as f64 / (g - 1) as f64, v0 + (v1 - v0) * j as f64 / (g - 1) as f64);
        format!("face {} at {}", x.1, xyz(q))
    };
    let (hi_pt, lo_pt) = (
        known.iter().max_by(|x, y| x.0.total_cmp(&y.0)).unwrap_or(&(NO_DATA, 0, 0)),
        known.iter().min_by(|x, y| x.0.total_cmp(&y.0)).unwrap_or(&(NO_DATA, 0, 0)),
    );
    let units = model.units.clone().map(|u| format!(" {u}")).unwrap_or_default();
    let mut lines = vec![format!(
        "deviation from {name} ({what}, {}): {g}×{g} exact surface points per face ({ms:.0} ms), interpolated between them",
        if point_stats.is_none() {
            "each point's distance to the closest point of the mesh"
        } else {
            "each showing the nearest cloud point measured on its face, as `nurbs deviation` measures it"
        }
    )];
    if let Some((v, total)) = &point_stats {
        let n = v.len().max(1) as f64;
        let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
        lines.push(format!(
            "cloud: {} of {total} points within {}{units} of the surface: max {}{units}, min {}{units}, mean {}{units}, \
             RMS {}{units}, within ±{}{units}: {:.1} %",
            v.len(),
            fmt(max),
            signed(hi),
            signed(lo),
            signed(v.iter().sum::<f64>() / n),
            fmt((v.iter().map(|x| x * x).sum::<f64>() / n).sqrt()),
            fmt(tol as f64),
            v.iter().filter(|x| x.abs() <= tol as f64).count() as f64 / n * 100.0
        ));
    }
    lines.extend([
        format!(
            "grid: max {}{units} ({}), min {}{units} ({}), mean {}{units}, RMS {}{units}",
            signed(hi_pt.0 as f64),
            at(hi_pt),
            signed(lo_pt.0 as f64),
            at(lo_pt),
            signed(mean),
            fmt(rms)
        ),
        format!(
            "within ±{}{units}: {within:.1} %; no reference within {}{units}: {:.1} % of the points on the kept faces",
            fmt(tol as f64),
            fmt(max),
            (kept - known.len()) as f64 / kept.max(1) as f64 * 100.0
        ),
        format!(
            "colours: green within ±{t}, yellow → red from +{t} to +{r} (the reference outside the surface, \
             along each face's normal Su × Sv), cyan → blue inside, grey no data{}",
            if a.range.is_none() {
                " (range: the 99th percentile of |deviation| rounded up; --range to set)"
            } else {
                ""
            },
            t = fmt(tol as f64),
            r = fmt(range as f64)
        ),
    ]);
    Ok(lines)
}

/// The smallest of 1, 2, 2.5, 5 × 10^k at or above `x` (> 0).
fn nice_up(x: f64) -> f64 {
    let k = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * k).find(|v| *v >= x * (1.0 - 1e-12)).unwrap_or(10.0 * k)
}
