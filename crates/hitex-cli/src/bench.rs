//! `hitex bench …`: CPU and GPU renderers on the same frames, in one run.
//!
//! Every pillar's benchmark reports rows of the same JSON shape:
//! `{"bench": NAME, "rows": [{"case", "backend", "adapter", "width", "height",
//! "frames", "ms_median", "fps_median"}], "ratios": [...], "parity": [...]}`.

use crate::{CliError, open_renderer, parse_size};
use hitex_core::scene::{Scene, showcase_scene};
use hitex_core::texture::Filter;
use hitex_render::cpu::simd::SimdLevel;
use hitex_render::{AnyRenderer, BackendChoice, Job, PreparedScene, Renderer, compare_rgba};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
#[allow(unused_imports)]
use std::path::Path;
use std::path::PathBuf;
use std::time::Instant;

/// Which backends a benchmark runs.
#[derive(Clone, Copy, clap::ValueEnum, PartialEq, Eq, Debug)]
pub enum Backends {
    /// CPU and GPU (the GPU is skipped, with a message, when no adapter exists).
    Both,
    /// CPU only.
    Cpu,
    /// GPU only.
    Gpu,
}

/// The CPU backend's SIMD levels a benchmark runs.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SimdArg {
    /// SIMD level of the CPU backend: one of this processor's (avx512, avx2,
    /// sse4, neon, scalar), or `all` for a scaling table over every level it
    /// runs (widest first; HITEX_SIMD also sets one)
    #[arg(long, value_name = "LEVEL|all")]
    pub simd: Option<String>,
}

impl SimdArg {
    /// The levels to run, widest first (none: the level detected or set by
    /// `HITEX_SIMD`, with each program's own cap); an error names the levels
    /// this processor runs.
    pub fn levels(&self) -> Result<Vec<SimdLevel>, CliError> {
        let runs = SimdLevel::available_levels();
        let names = || runs.iter().map(|l| l.name()).collect::<Vec<_>>().join(", ");
        match self.simd.as_deref().map(str::trim) {
            None => Ok(Vec::new()),
            Some(a) if a.eq_ignore_ascii_case("all") => Ok(runs),
            Some(n) => match SimdLevel::from_name(n) {
                Some(l) if l.available() => Ok(vec![l]),
                Some(l) => Err(CliError::Input(format!("--simd {n}: this processor lacks {l}; it runs {}", names()))),
                None => {
                    Err(CliError::Input(format!("--simd {n} names no level; this processor runs {} (or all)", names())))
                }
            },
        }
    }
}

/// The cases a benchmark runs.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct CaseArg {
    /// Run only these cases (comma-separated): a name as the table prints it,
    /// or its first part (`teapot` runs every `teapot-…` case); all by default
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub cases: Vec<String>,
}

impl CaseArg {
    /// `all` filtered to the cases asked for: a name given whole selects that
    /// case, otherwise every case it begins followed by a dash. An error names
    /// every case when a name selects none.
    pub fn select<T>(&self, all: Vec<(String, T)>) -> Result<Vec<(String, T)>, CliError> {
        if self.cases.is_empty() {
            return Ok(all);
        }
        let names: Vec<&str> = all.iter().map(|(n, _)| n.as_str()).collect();
        let picks = |c: &str, n: &str| {
            n == c || (!names.contains(&c) && n.strip_prefix(c).is_some_and(|rest| rest.starts_with('-')))
        };
        let asked: Vec<&str> = self.cases.iter().map(|c| c.trim()).collect();
        if let Some(bad) = asked.iter().find(|c| !names.iter().any(|n| picks(c, n))) {
            return Err(CliError::Input(format!("--cases {bad}: no such case; the cases are {}", names.join(", "))));
        }
        let keep: Vec<bool> = names.iter().map(|n| asked.iter().any(|c| picks(c, n))).collect();
        Ok(all.into_iter().zip(keep).filter(|(_, k)| *k).map(|(c, _)| c).collect())
    }
}

/// Arguments of `hitex bench texture`.
#[derive(clap::Args, Debug)]
pub struct TextureArgs {
    /// Print JSON on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Frames per case (the camera makes one full orbit over them).
    #[arg(long, default_value_t = 24)]
    pub frames: u32,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Backends to run.
    #[arg(long, value_enum, default_value_t = Backends::Both)]
    pub backends: Backends,
    /// Also write a bar chart (SVG) of the medians.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    #[command(flatten)]
    pub simd: SimdArg,
    #[command(flatten)]
    pub cases: CaseArg,
}

/// One measured (case, backend) pair.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Case name.
    pub case: String,
    /// "cpu" or "gpu".
    pub backend: String,
    /// Adapter or thread count.
    pub adapter: String,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Timed frames.
    pub frames: u32,
    /// Median frame time.
    pub ms_median: f64,
    /// 1000 / ms_median.
    pub fps_median: f64,
    /// Pixels of the frame per second at the median, in millions.
    pub mpix_s: f64,
    /// The CPU backend's SIMD level ("" for the GPU).
    pub simd: String,
    /// CPU rows: whether the first frame is the same image, bit for bit, as
    /// the first CPU row's of the case (the levels must agree; null for the GPU).
    pub same_image: Option<bool>,
}

/// GPU median over CPU median for a case.
#[derive(Debug, Clone, Serialize)]
pub struct Ratio {
    /// Case name.
    pub case: String,
    /// gpu ms / cpu ms (> 1: the CPU is faster).
    pub gpu_over_cpu: f64,
}

/// Agreement of the two backends on the first frame of a case.
#[derive(Debug, Clone, Serialize)]
pub struct Parity {
    /// Case name.
    pub case: String,
    /// Mean absolute channel difference in 8-bit steps.
    pub mean_abs: f64,
    /// 99th percentile of the per-pixel max channel difference.
    pub p99: u8,
}

/// A whole benchmark report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Benchmark name.
    pub bench: String,
    /// Measurements.
    pub rows: Vec<Row>,
    /// GPU/CPU ratios per case.
    pub ratios: Vec<Ratio>,
    /// CPU-vs-GPU image agreement per case.
    pub parity: Vec<Parity>,
}

/// Median of a non-empty list.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

fn progress(total: u64, quiet: bool) -> ProgressBar {
    if quiet && !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(total);
    pb.set_style(
        ProgressStyle::with_template("{prefix:>24} [{bar:30}] {pos}/{len} frames {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb
}

/// A benchmark case: the job of frame `i` of `n` at `w`×`h` (the camera
/// orbits once over the frames), rendered the same way on every backend.
pub type CaseFn<'a> = Box<dyn Fn(u32, u32, u32, u32) -> Result<Job<'a>, CliError> + 'a>;

/// The case of a prepared content seen by a camera orbiting once.
pub fn orbit_case<'a>(
    camera: hitex_core::scene::Camera,
    job: impl Fn(hitex_core::scene::Camera) -> Job<'a> + 'a,
) -> CaseFn<'a> {
    Box::new(move |i, k, _, _| Ok(job(camera.orbit(std::f32::consts::TAU * i as f32 / k as f32))))
}

/// Runs `cases` on the chosen backends: a warm-up frame, then `frames` timed
/// frames orbiting the camera once; compares the first frame of both backends.
pub fn run_cases(
    name: &str,
    cases: &[(String, Scene)],
    frames: u32,
    size: (u32, u32),
    which: Backends,
    levels: &[SimdLevel],
    quiet: bool,
) -> Result<Report, CliError> {
    let prepared: Vec<(String, PreparedScene)> =
        cases.iter().map(|(n, s)| (n.clone(), PreparedScene::new(s))).collect();
    let fns: Vec<(String, CaseFn)> = prepared
        .iter()
        .map(|(n, p)| (n.clone(), orbit_case(p.camera, move |camera| Job::Scene { scene: p, camera })))
        .collect();
    run_case_fns(name, &fns, frames, size, which, levels, quiet)
}

/// Like [`run_cases`] for arbitrary frame functions. The CPU backend runs
/// once per SIMD level in `levels` (its rows name the level; ratios and
/// parity are against the first).
pub fn run_case_fns(
    name: &str,
    cases: &[(String, CaseFn)],
    frames: u32,
    (w, h): (u32, u32),
    which: Backends,
    levels: &[SimdLevel],
    quiet: bool,
) -> Result<Report, CliError> {
    let mut backends: Vec<(&str, AnyRenderer, Option<SimdLevel>)> = Vec::new();
    if which != Backends::Gpu {
        if levels.is_empty() {
            backends.push(("cpu", open_renderer(BackendChoice::Cpu)?, None));
        }
        for &l in levels {
            backends.push(("cpu", open_renderer(BackendChoice::Cpu)?, Some(l)));
        }
    }
    if which != Backends::Cpu {
        match open_renderer(BackendChoice::Gpu) {
            Ok(g) => backends.push(("gpu", g, None)),
            Err(CliError::Internal(m)) | Err(CliError::Input(m)) if which == Backends::Both => {
                eprintln!("hitex bench: GPU backend skipped: {m}");
            }
            Err(e) => return Err(e),
        }
    }
    let frames = frames.max(1);
    let mut rows = Vec::new();
    let mut parity = Vec::new();
    let before = hitex_render::cpu::simd::level();
    for (case, job) in cases {
        let mut first_frames = Vec::new();
        let mut level_frames: Vec<(SimdLevel, hitex_render::Frame)> = Vec::new();
        for (kind, r, level) in backends.iter_mut() {
            if let Some(l) = level {
                hitex_render::cpu::simd::set_level(*l).map_err(|e| CliError::Internal(e.to_string()))?;
            }
            let pb = progress(frames as u64, quiet);
            pb.set_prefix(match level {
                Some(l) if levels.len() > 1 => format!("{case} {kind} {l}"),
                _ => format!("{case} {kind}"),
            });
            // warm-up: uploads, shader compilation, caches
            let f0 = r.render(&job(0, frames, w, h)?, w, h)?.frame;
            if *kind == "cpu" {
                if level_frames.is_empty() {
                    first_frames.push(f0.clone());
                }
                level_frames.push((level.unwrap_or(before), f0));
            } else {
                first_frames.push(f0);
            }
            let mut times = Vec::new();
            for i in 0..frames {
                let t = Instant::now();
                let f = r.render(&job(i, frames, w, h)?, w, h)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
                std::hint::black_box(&f);
                pb.inc(1);
            }
            pb.finish_and_clear();
            let ms = median(&mut times);
            rows.push(Row {
                case: case.clone(),
                backend: kind.to_string(),
                adapter: r.name(),
                width: w,
                height: h,
                frames,
                ms_median: ms,
                fps_median: 1e3 / ms,
                mpix_s: w as f64 * h as f64 / (ms * 1e3),
                simd: match (*kind, level) {
                    ("cpu", Some(l)) => l.to_string(),
                    ("cpu", None) => job(0, frames, w, h)?.cpu_simd_level().to_string(),
                    _ => String::new(),
                },
                same_image: (*kind == "cpu")
                    .then(|| level_frames.first().is_some_and(|f| level_frames.last().is_some_and(|l| l.1 == f.1))),
            });
        }
        if first_frames.len() == 2 {
            let (d, _) = compare_rgba(&first_frames[0].rgba, &first_frames[1].rgba);
            parity.push(Parity { case: case.clone(), mean_abs: d.mean_abs, p99: d.p99 });
        }
    }
    hitex_render::cpu::simd::set_level(before).map_err(|e| CliError::Internal(e.to_string()))?;
    let mut ratios = Vec::new();
    for (case, _) in cases {
        let cpu = rows.iter().find(|r| &r.case == case && r.backend == "cpu");
        let gpu = rows.iter().find(|r| &r.case == case && r.backend == "gpu");
        if let (Some(c), Some(g)) = (cpu, gpu) {
            ratios.push(Ratio { case: case.clone(), gpu_over_cpu: g.ms_median / c.ms_median });
        }
    }
    Ok(Report { bench: name.to_string(), rows, ratios, parity })
}

/// Prints a report as a table.
pub fn print_table(r: &Report) {
    if r.rows.iter().any(|x| x.backend == "cpu") {
        say!("processor: {}", hitex_render::cpu::simd::processor());
    }
    say!(
        "{:<22} {:<4} {:<44} {:>10} {:>8} {:>8} {:>8} {:>7}",
        "case",
        "be",
        "adapter",
        "size",
        "ms",
        "fps",
        "Mpix/s",
        "simd"
    );
    let levels: Vec<&str> = {
        let mut v: Vec<&str> = r.rows.iter().filter(|x| x.backend == "cpu").map(|x| x.simd.as_str()).collect();
        v.dedup();
        v.sort_by_key(|n| std::cmp::Reverse(SimdLevel::from_name(n).map_or(0, |l| l.width())));
        v.dedup();
        v
    };
    for row in &r.rows {
        say!(
            "{:<22} {:<4} {:<44} {:>10} {:>8.2} {:>8.1} {:>8.1} {:>7}",
            row.case,
            row.backend,
            row.adapter,
            format!("{}x{}", row.width, row.height),
            row.ms_median,
            row.fps_median,
            row.mpix_s,
            row.simd
        );
    }
    for q in &r.ratios {
        say!(
            "{:<22} gpu/cpu median ratio {:.2} ({})",
            q.case,
            q.gpu_over_cpu,
            if q.gpu_over_cpu > 1.0 { "CPU faster" } else { "GPU faster" }
        );
    }
    for p in &r.parity {
        say!("{:<22} cpu vs gpu first frame: mean |Δ| {:.3}, p99 {} (8-bit steps)", p.case, p.mean_abs, p.p99);
    }
    if levels.len() > 1 {
        print_scaling(r, &levels);
    }
}

/// The CPU rows of several SIMD levels side by side: median ms per level,
/// the widest level's speed-up over the narrowest, and whether every level
/// rendered the same image.
fn print_scaling(r: &Report, levels: &[&str]) {
    say_part!("{:<22}", "cpu ms by SIMD level");
    for l in levels {
        say_part!(" {l:>9}");
    }
    say!("  {:>9}  same image", "speed-up");
    let mut cases: Vec<&str> = r.rows.iter().map(|x| x.case.as_str()).collect();
    cases.dedup();
    for case in cases {
        let ms: Vec<Option<&Row>> = levels
            .iter()
            .map(|l| r.rows.iter().find(|x| x.case == case && x.backend == "cpu" && x.simd == *l))
            .collect();
        say_part!("{case:<22}");
        for m in &ms {
            match m {
                Some(row) => say_part!(" {:>9.2}", row.ms_median),
                None => say_part!(" {:>9}", "-"),
            }
        }
        let speedup = match (ms.first().copied().flatten(), ms.last().copied().flatten()) {
            (Some(a), Some(b)) => format!("{:.2}", b.ms_median / a.ms_median),
            _ => "-".into(),
        };
        let same = ms.iter().flatten().all(|x| x.same_image != Some(false));
        say!("  {speedup:>9}  {}", if same { "yes" } else { "NO" });
    }
}

/// Writes a horizontal bar chart of the medians as SVG.
pub fn write_chart(r: &Report, path: &std::path::Path) -> Result<(), CliError> {
    let bar_h = 22.0;
    let left = 260.0;
    let width = 760.0;
    let max = r.rows.iter().map(|x| x.ms_median).fold(1e-9, f64::max);
    let height = 60.0 + bar_h * r.rows.len() as f64;
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{width}' height='{height}' font-family='sans-serif' font-size='13'>\n\
         <rect width='100%' height='100%' fill='white'/>\n<text x='10' y='22' font-size='15'>hitex bench {}: median ms per frame (shorter is faster)</text>\n",
        r.bench
    );
    for (i, row) in r.rows.iter().enumerate() {
        let y = 40.0 + i as f64 * bar_h;
        let w = (width - left - 80.0) * row.ms_median / max;
        let color = if row.backend == "cpu" { "#3b7dd8" } else { "#d8703b" };
        s += &format!(
            "<text x='10' y='{:.0}'>{} · {}</text><rect x='{left}' y='{:.0}' width='{w:.1}' height='{:.0}' fill='{color}'/><text x='{:.1}' y='{:.0}'>{:.1} ms</text>\n",
            y + 15.0,
            row.case,
            row.backend,
            y + 3.0,
            bar_h - 6.0,
            left + w + 6.0,
            y + 15.0,
            row.ms_median
        );
    }
    s += "</svg>\n";
    hitex_io::write_atomic(path, s.as_bytes()).map_err(CliError::from)
}

/// `hitex bench texture`.
pub fn texture(args: TextureArgs) -> Result<(), CliError> {
    let levels = args.simd.levels()?;
    let base = showcase_scene();
    let cases: Vec<(String, Scene)> =
        [("trilinear", Filter::Trilinear), ("bilinear", Filter::Bilinear), ("nearest", Filter::Nearest)]
            .into_iter()
            .map(|(n, f)| {
                let mut s = base.clone();
                for m in &mut s.materials {
                    m.sampler.filter = f;
                }
                (n.to_string(), s)
            })
            .collect();
    let cases = args.cases.select(cases)?;
    if !args.json {
        say!(
            "hitex bench texture: showcase scene ({} triangles), {}x{}, {} frames per case orbiting once; median of each",
            base.triangle_count(),
            args.size.0,
            args.size.1,
            args.frames
        );
    }
    let report = run_cases("texture", &cases, args.frames, args.size, args.backends, &levels, args.json)?;
    if args.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| CliError::Internal(e.to_string()))?;
        say!("{text}");
    } else {
        print_table(&report);
    }
    if let Some(p) = &args.chart {
        write_chart(&report, p)?;
        if !args.json {
            say!("chart: {}", p.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    #[test]
    fn cases_are_chosen_by_name_or_first_part() {
        let all = || ["teapot-shaded", "teapot-shaded-generic", "spray-shaded"].map(|n| (n.to_string(), ())).to_vec();
        let pick = |c: &[&str]| {
            let arg = CaseArg { cases: c.iter().map(|s| s.to_string()).collect() };
            arg.select(all()).map(|v| v.into_iter().map(|(n, _)| n).collect::<Vec<_>>())
        };
        assert_eq!(pick(&[]).unwrap().len(), 3);
        assert_eq!(pick(&["teapot"]).unwrap(), ["teapot-shaded", "teapot-shaded-generic"]);
        assert_eq!(pick(&["teapot-shaded"]).unwrap(), ["teapot-shaded"]);
        assert_eq!(
            pick(&["spray-shaded", "teapot-shaded-generic"]).unwrap(),
            ["teapot-shaded-generic", "spray-shaded"]
        );
        // a prefix must end at a dash, and a name selecting nothing is refused with the list
        let Err(CliError::Input(e)) = pick(&["tea"]) else { panic!("--cases tea accepted") };
        assert!(e.contains("--cases tea") && e.contains("spray-shaded"), "{e}");
    }
}

/// Arguments of `hitex bench nurbs`.
#[derive(clap::Args, Debug)]
pub struct NurbsArgs {
    /// Print JSON on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Frames per case (one full turn over them).
    #[arg(long, default_value_t = 24)]
    pub frames: u32,
    /// Frame size, WIDTHxHEIGHT (the paper's is 512x512).
    #[arg(long, value_parser = parse_size, default_value = "512x512")]
    pub size: (u32, u32),
    /// Backends to run.
    #[arg(long, value_enum, default_value_t = Backends::Both)]
    pub backends: Backends,
    /// Also write a bar chart (SVG) of the medians.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    #[command(flatten)]
    pub simd: SimdArg,
    #[command(flatten)]
    pub cases: CaseArg,
}

/// `hitex bench nurbs`: the paper's Table 1 models, shaded and with isophotes.
pub fn nurbs(args: NurbsArgs) -> Result<(), CliError> {
    let levels = args.simd.levels()?;
    use hitex_render::nurbs::NurbsMode;
    let mut wanted = Vec::new();
    for name in ["surface", "teapot", "spray"] {
        for (mode_name, mode, prepared_kernels) in [
            ("shaded", NurbsMode::Shaded, true),
            ("isophote", NurbsMode::Isophote, true),
            ("shaded-generic", NurbsMode::Shaded, false),
        ] {
            wanted.push((format!("{name}-{mode_name}"), (name, mode, prepared_kernels)));
        }
    }
    let mut prepared = Vec::new();
    for (case, (name, mode, prepared_kernels)) in args.cases.select(wanted)? {
        let model = hitex_io::models::load_model(name)?;
        let density = if name == "spray" { 4 } else { 8 };
        {
            let mut p = crate::nurbs_cmd::prepare(&model, hitex_render::nurbs::Density::Fixed(density), None).0;
            p.mode = mode;
            p.prepared_kernels = prepared_kernels;
            prepared.push((case, p));
        }
    }
    let fns: Vec<(String, CaseFn)> = prepared
        .iter()
        .map(|(n, p)| (n.clone(), orbit_case(p.camera, move |camera| Job::Nurbs { model: p, camera })))
        .collect();
    if !args.json {
        say!(
            "hitex bench nurbs: per-pixel exact evaluation, {}x{}, {} frames per case turning once; paper (GeForce 7900 GTX, 2006): surface 212 fps, teapot 201 fps, spray 126 fps; '-generic' = any-degree loops instead of the prepared bicubic kernels",
            args.size.0,
            args.size.1,
            args.frames
        );
    }
    let report = run_case_fns("nurbs", &fns, args.frames, args.size, args.backends, &levels, args.json)?;
    if args.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| CliError::Internal(e.to_string()))?;
        say!("{text}");
    } else {
        print_table(&report);
    }
    if let Some(p) = &args.chart {
        write_chart(&report, p)?;
    }
    Ok(())
}
