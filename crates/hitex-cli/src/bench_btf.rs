//! `hitex bench btf`: the paper's Fig. 5/6 setting — a 256×256 quad in a
//! 640×480 frame under a moving light — for every codebook layout,
//! uncompressed and BC1, on both backends in one run; plus BC1 quality per
//! layout (the paper's SNR), the encoders compared, and the texture-cache
//! model's load efficiency.

use crate::bench::{Backends, CaseFn, Report, median, print_table, run_case_fns};
use crate::btf_cmd::{index_with_progress, synth_with_progress};
use crate::{CliError, parse_size};
use glam::Vec3;
use hitex_core::btf::cache::{CacheConfig, CacheModel};
use hitex_core::btf::synth::{Material, SynthOptions};
use hitex_core::btf::{Btf, Codebook, Layout};
use hitex_core::scene::Camera;
use hitex_core::texture::bc1::{self, Bc1Encoder};
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::cpu::btf::{BtfProgram, fragments_in_quad_order};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `hitex bench btf`.
#[derive(clap::Args, Debug)]
pub struct BtfArgs {
    /// Print JSON on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Frames per case (the light turns once around the quad over them).
    #[arg(long, default_value_t = 16)]
    pub frames: u32,
    /// Frame size, WIDTHxHEIGHT (the paper's is 640x480 with a 256×256 quad).
    #[arg(long, value_parser = parse_size, default_value = "640x480")]
    pub size: (u32, u32),
    /// Side of the quad on screen in pixels.
    #[arg(long, default_value_t = 256)]
    pub quad: u32,
    /// Material of the procedural BTF.
    #[arg(long, default_value = "corduroy")]
    pub material: String,
    /// Sample side in texels (the paper's is 32).
    #[arg(long, default_value_t = 32)]
    pub sample: u32,
    /// Layouts to run (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    pub layouts: Option<Vec<String>>,
    /// Skip the BC1 cases and the comparison of BC1 encoders.
    #[arg(long)]
    pub no_bc1: bool,
    /// Backends to run.
    #[arg(long, value_enum, default_value_t = Backends::Both)]
    pub backends: Backends,
    /// Texture-cache model capacity in KiB.
    #[arg(long, default_value_t = 16)]
    pub cache_kib: u32,
    /// Texture-cache model associativity.
    #[arg(long, default_value_t = 4)]
    pub cache_ways: u32,
    /// Also write a chart (SVG) of frame rates and load efficiency, like Fig. 5/6.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Also run each layout minified (the index map repeated 8 times over
    /// the quad) without and with MIP mapping: cases `layout-X-r8` and
    /// `layout-X-r8-mip`.
    #[arg(long)]
    pub mip: bool,
    /// Also run each layout from a local-PCA codebook of CLUSTERS,COMPONENTS
    /// (cases `layout-X-pca`), with its ratio and PSNR in the compression table.
    #[arg(long, value_parser = crate::btf_cmd::parse_pca)]
    pub pca: Option<hitex_core::btf::pca::PcaOptions>,
    #[command(flatten)]
    pub simd: crate::bench::SimdArg,
}

/// BC1 quality of one layout.
#[derive(Debug, Clone, Serialize)]
pub struct Snr {
    /// Layout case name.
    pub case: String,
    /// PSNR of the decoded codebook against the original, RGB, dB.
    pub psnr_db: f64,
    /// The paper's figure for this layout's group.
    pub paper_db: f64,
    /// Encoding time of the whole codebook, ms.
    pub encode_ms: f64,
}

/// One encoder on one codebook.
#[derive(Debug, Clone, Serialize)]
pub struct EncoderRow {
    /// Encoder name.
    pub encoder: String,
    /// Texels encoded.
    pub texels: u64,
    /// Time, ms.
    pub ms: f64,
    /// PSNR, dB.
    pub psnr_db: f64,
}

/// Size and quality of one compressed codebook.
#[derive(Debug, Clone, Serialize)]
pub struct CompressionRow {
    /// Case name (`layout-X-bc1`, `layout-X-pca`).
    pub case: String,
    /// Bytes of the compressed codebook without the layouts' padding (BC1:
    /// 4 bits a texel; PCA: basis and coefficients as half floats, 16-bit
    /// cluster ids).
    pub bytes: u64,
    /// The BTF's RGB8 texels over `bytes`.
    pub ratio: f64,
    /// PSNR of the decoded codebook against the raw 8-bit texels, RGB, dB.
    pub psnr_db: f64,
}

/// Texture-cache model of one case on the first frame.
#[derive(Debug, Clone, Serialize)]
pub struct CacheRow {
    /// Case name.
    pub case: String,
    /// Pixels shaded.
    pub pixels: u64,
    /// Codebook texture instructions per pixel.
    pub reads_per_pixel: f64,
    /// Texels touched per pixel.
    pub texels_per_pixel: f64,
    /// Hit rate of texel accesses.
    pub hit_rate: f64,
    /// Bytes fetched from memory per pixel.
    pub bytes_per_pixel: f64,
    /// Bytes fetched per texture instruction.
    pub bytes_per_read: f64,
    /// Bytes fetched per texel the filter touches.
    pub bytes_per_texel: f64,
    /// Load efficiency: bytes per touched texel of layout (a) uncompressed
    /// over this case's (memory traffic per unit of texture work; > 1 is better).
    pub load_efficiency: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct BtfReport {
    /// Frame timings, ratios and parity, as every bench.
    #[serde(flatten)]
    pub timing: Report,
    /// Material and codebook.
    pub material: String,
    /// Codebook bytes as RGBA8.
    pub codebook_bytes: u64,
    /// Cache model geometry.
    pub cache: String,
    /// BC1 quality per layout.
    pub snr: Vec<Snr>,
    /// Encoders compared on layout (a).
    pub encoders: Vec<EncoderRow>,
    /// Cache model per case.
    pub cache_model: Vec<CacheRow>,
    /// Compression ratio and quality per compressed case.
    pub compression: Vec<CompressionRow>,
}

fn paper_snr(l: Layout) -> f64 {
    match l {
        Layout::A | Layout::B => 37.2,
        Layout::C | Layout::C2 | Layout::D => 35.6,
        Layout::E | Layout::E2 | Layout::F => 33.9,
    }
}

/// The camera that shows a 2×2 quad at the origin as `quad` pixels square in a frame `height` pixels high.
fn quad_camera(quad: u32, height: u32) -> Result<Camera, CliError> {
    let fov: f32 = 35.0;
    let d = height as f32 / (quad as f32 * (fov.to_radians() / 2.0).tan());
    Camera::new(Vec3::new(0.0, 0.0, d), Vec3::ZERO, Vec3::Y, fov, d * 0.1, d * 4.0)
        .map_err(|e| CliError::Input(e.to_string()))
}

fn light_at(i: u32, k: u32) -> Vec3 {
    let a = std::f32::consts::TAU * i as f32 / k.max(1) as f32;
    Vec3::new(a.cos(), a.sin(), 1.0) * 4.0
}

fn case_name(l: Layout, bc1: bool) -> String {
    format!("layout-{}{}", l.name(), if bc1 { "-bc1" } else { "" })
}

/// `hitex bench btf`.
pub fn btf(args: BtfArgs) -> Result<(), CliError> {
    let quiet = args.json;
    let levels = args.simd.levels()?;
    let material = Material::parse(&args.material)
        .ok_or_else(|| CliError::Input(format!("unknown material '{}'", args.material)))?;
    let layouts: Vec<Layout> = match &args.layouts {
        None => Layout::ALL.to_vec(),
        Some(v) => v
            .iter()
            .map(|s| Layout::parse(s).ok_or_else(|| CliError::Input(format!("unknown layout '{s}'"))))
            .collect::<Result<_, _>>()?,
    };
    let opts = SynthOptions { size: args.sample, ..Default::default() };
    let t = Instant::now();
    let btf: Btf = synth_with_progress(material, &opts, quiet)?;
    let synth_s = t.elapsed().as_secs_f64();
    let index = index_with_progress(&btf, 128, 1, 3, quiet)?;
    if !quiet {
        say!(
            "hitex bench btf: {} BTF, {} images of {}x{} texels ({:.0} MiB RGBA8, made in {synth_s:.1} s), 128x128 index, a {}x{} quad in a {}x{} frame, light turning once over {} frames",
            material.name(),
            btf.images(),
            btf.width(),
            btf.height(),
            btf.gpu_bytes() as f64 / 1048576.0,
            args.quad,
            args.quad,
            args.size.0,
            args.size.1,
            args.frames
        );
        say!(
            "paper (GeForce 6800 Ultra, 2005): (f) fastest; BC1 as fast or faster; SNR (a),(b) 37.2, (c),(d) 35.6, (e),(f) 33.9 dB"
        );
    }
    let camera = quad_camera(args.quad, args.size.1)?;
    let (w, h) = args.size;
    let mut reports: Vec<Report> = Vec::new();
    let mut snr = Vec::new();
    let mut cache_rows = Vec::new();
    let cache_cfg = CacheConfig { bytes: args.cache_kib << 10, ways: args.cache_ways, bc1: false };
    // (layout, BC1, minified: none / without MIP / with MIP)
    let mut variants: Vec<(Layout, bool, u8)> = layouts
        .iter()
        .flat_map(|&l| if args.no_bc1 { vec![(l, false, 0)] } else { vec![(l, false, 0), (l, true, 0)] })
        .collect();
    let mip = if args.mip {
        variants.extend(layouts.iter().flat_map(|&l| [(l, false, 1), (l, false, 2)]));
        Some(crate::btf_cmd::mip_with_progress(&btf, &index, quiet)?)
    } else {
        None
    };
    let mut compression = Vec::new();
    let rgb8 = btf.texels().len() as u64;
    let pca = match args.pca {
        Some(opts) => {
            variants.extend(layouts.iter().map(|&l| (l, false, 3)));
            let (p, psnr) = crate::btf_cmd::pca_with_progress(&btf, opts, quiet)?;
            let bytes = p.bytes();
            let name = format!("pca-{}x{}", opts.clusters, opts.components);
            compression.push(CompressionRow { case: name, bytes, ratio: rgb8 as f64 / bytes as f64, psnr_db: psnr });
            Some(p)
        }
        None => None,
    };
    for &(layout, compressed, minified) in &variants {
        let name = case_name(layout, compressed) + ["", "-r8", "-r8-mip", "-pca"][minified as usize];
        let t = Instant::now();
        let enc = compressed.then_some(Bc1Encoder::Ispc);
        let repeats = if minified == 1 || minified == 2 { 8.0 } else { 1.0 };
        let prepared = match (&mip, &pca, minified) {
            (Some(m), _, 2) => PreparedBtf::with_mip(m, layout, enc, BtfSurface::quad(2.0, repeats))?,
            (_, Some(p), 3) => PreparedBtf::with_pca(p, layout, index.clone(), BtfSurface::quad(2.0, repeats))?,
            _ => PreparedBtf::new(&btf, layout, enc, index.clone(), BtfSurface::quad(2.0, repeats))?,
        };
        let prep_ms = t.elapsed().as_secs_f64() * 1e3;
        if compressed {
            // quality and time of BC1 on this layout
            let original = Codebook::build(&btf, layout).map_err(|e| CliError::Input(e.to_string()))?;
            let psnr = bc1::psnr_rgb(&original.texels, &prepared.codebook.texels);
            let t = Instant::now();
            let blocks =
                bc1::encode(&original.texels, original.width, original.height, original.depth, Bc1Encoder::Ispc)
                    .map_err(|e| CliError::Internal(e.to_string()))?;
            let encode_ms = t.elapsed().as_secs_f64() * 1e3;
            // 4 bits a texel, without the layout's padding (as the PCA's bytes are counted)
            let bytes = rgb8 / 6;
            std::hint::black_box(blocks);
            compression.push(CompressionRow {
                case: name.clone(),
                bytes,
                ratio: rgb8 as f64 / bytes as f64,
                psnr_db: psnr,
            });
            snr.push(Snr { case: name.clone(), psnr_db: psnr, paper_db: paper_snr(layout), encode_ms });
        }
        // texture-cache model over the first frame's fragments
        let frame = prepared.frame(&camera, light_at(0, args.frames), w, h);
        let frags = fragments_in_quad_order(&prepared, &frame, w, h);
        let program = BtfProgram::new(&prepared, &frame);
        let cfg = CacheConfig { bc1: compressed, ..cache_cfg };
        let cb = &prepared.codebook;
        let mut model = CacheModel::new(cfg, cb.width, cb.height).map_err(|e| CliError::Input(e.to_string()))?;
        // the quad faces the camera: its footprint, index texels per pixel, is
        // about the same everywhere, so the MIP case is modelled at that level
        let lod = if minified == 2 { (index.width as f32 * repeats / args.quad as f32).log2().max(0.0) } else { 0.0 };
        for v in &frags {
            program.shade_linear_at(v, lod, &mut model);
        }
        let px = frags.len().max(1) as f64;
        cache_rows.push(CacheRow {
            case: name.clone(),
            pixels: frags.len() as u64,
            reads_per_pixel: model.reads as f64 / px,
            texels_per_pixel: model.accesses as f64 / px,
            hit_rate: model.hit_rate(),
            bytes_per_pixel: model.bytes_fetched() as f64 / px,
            bytes_per_read: model.bytes_fetched() as f64 / model.reads.max(1) as f64,
            bytes_per_texel: model.bytes_fetched() as f64 / model.accesses.max(1) as f64,
            load_efficiency: 0.0,
        });
        // timing on both backends
        let f: CaseFn =
            Box::new(|i, k, _, _| Ok(hitex_render::Job::Btf { surface: &prepared, camera, light: light_at(i, k) }));
        if !quiet {
            eprintln!("{name}: prepared in {prep_ms:.0} ms");
        }
        reports.push(run_case_fns("btf", &[(name, f)], args.frames, args.size, args.backends, &levels, quiet)?);
    }
    // load efficiency relative to (a) uncompressed
    let base = cache_rows.iter().find(|c| c.case == "layout-a").map(|c| c.bytes_per_texel);
    for c in &mut cache_rows {
        c.load_efficiency = match base {
            Some(b) if c.bytes_per_texel > 0.0 => b / c.bytes_per_texel,
            _ => f64::NAN,
        };
    }
    // the encoder comparison is BC1's: skipped with the BC1 cases (its
    // cluster fit takes most of a run's set-up)
    let encoders = if args.no_bc1 { Vec::new() } else { compare_encoders(&btf)? };
    let mut timing = Report { bench: "btf".into(), rows: vec![], ratios: vec![], parity: vec![] };
    for r in reports {
        timing.rows.extend(r.rows);
        timing.ratios.extend(r.ratios);
        timing.parity.extend(r.parity);
    }
    let report = BtfReport {
        timing,
        material: material.name().into(),
        codebook_bytes: btf.gpu_bytes(),
        cache: format!(
            "{} KiB, {}-way LRU, lines = one 4x4 block (64 B RGBA8, 8 B BC1)",
            args.cache_kib, args.cache_ways
        ),
        snr,
        encoders,
        cache_model: cache_rows,
        compression,
    };
    if args.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| CliError::Internal(e.to_string()))?;
        say!("{text}");
    } else {
        print_report(&report);
    }
    if let Some(p) = &args.chart {
        write_btf_chart(&report, p)?;
    }
    Ok(())
}

/// The encoders on layout (a) of `btf`: the ISPC kernels and texpresso's
/// range fit on the whole codebook, texpresso's (slow) cluster fit on its
/// first 1024 rows.
fn compare_encoders(btf: &Btf) -> Result<Vec<EncoderRow>, CliError> {
    let cb = Codebook::build(btf, Layout::A).map_err(|e| CliError::Input(e.to_string()))?;
    let mut rows = Vec::new();
    for (enc, rows_used) in [
        (Bc1Encoder::Ispc, cb.height),
        (Bc1Encoder::TexpressoRange, cb.height),
        (Bc1Encoder::TexpressoCluster, cb.height.min(1024)),
    ] {
        let bytes = &cb.texels[..(cb.width * rows_used * 4) as usize];
        let mut times = Vec::new();
        let mut blocks = Vec::new();
        for _ in 0..if enc == Bc1Encoder::TexpressoCluster { 1 } else { 3 } {
            let t = Instant::now();
            blocks = bc1::encode(bytes, cb.width, rows_used, 1, enc).map_err(|e| CliError::Internal(e.to_string()))?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let decoded = bc1::decode(&blocks, cb.width, rows_used, 1).map_err(|e| CliError::Internal(e.to_string()))?;
        rows.push(EncoderRow {
            encoder: enc.name().into(),
            texels: cb.width as u64 * rows_used as u64,
            ms: median(&mut times),
            psnr_db: bc1::psnr_rgb(bytes, &decoded),
        });
    }
    Ok(rows)
}

fn print_report(r: &BtfReport) {
    print_table(&r.timing);
    if !r.snr.is_empty() {
        say!();
        say!("BC1 quality per layout (PSNR of the decoded codebook, RGB, ISPC encoder):");
        say!("{:<16} {:>9} {:>9} {:>12}", "case", "dB", "paper dB", "encode ms");
    }
    for s in &r.snr {
        say!("{:<16} {:>9.2} {:>9.1} {:>12.0}", s.case, s.psnr_db, s.paper_db, s.encode_ms);
    }
    if !r.encoders.is_empty() {
        say!();
        say!("BC1 encoders on layout (a):");
    }
    for e in &r.encoders {
        say!(
            "  {:<18} {:>9} texels {:>9.0} ms {:>8.1} Mtexel/s {:>7.2} dB",
            e.encoder,
            e.texels,
            e.ms,
            e.texels as f64 / e.ms / 1e3,
            e.psnr_db
        );
    }
    if !r.compression.is_empty() {
        say!();
        say!(
            "compressed codebooks (ratio: the BTF's RGB8 texels over the compressed bytes, both without the layouts' padding; PSNR against them, RGB):"
        );
        say!("{:<16} {:>12} {:>9} {:>9}", "case", "bytes", "ratio", "dB");
        for c in &r.compression {
            say!("{:<16} {:>12} {:>9} {:>9.2}", c.case, c.bytes, format!("1:{:.1}", c.ratio), c.psnr_db);
        }
    }
    say!();
    say!("texture-cache model ({}), first frame:", r.cache);
    say!(
        "{:<16} {:>8} {:>10} {:>10} {:>8} {:>10} {:>10} {:>11} {:>10}",
        "case",
        "pixels",
        "reads/px",
        "texels/px",
        "hit %",
        "bytes/px",
        "bytes/read",
        "bytes/texel",
        "load eff."
    );
    for c in &r.cache_model {
        say!(
            "{:<16} {:>8} {:>10.1} {:>10.1} {:>8.2} {:>10.1} {:>10.2} {:>11.3} {:>10.2}",
            c.case,
            c.pixels,
            c.reads_per_pixel,
            c.texels_per_pixel,
            c.hit_rate * 100.0,
            c.bytes_per_pixel,
            c.bytes_per_read,
            c.bytes_per_texel,
            c.load_efficiency
        );
    }
}

/// Two panels like the paper's Fig. 5 and 6: frames per second per case and
/// backend, and the model's load efficiency per case.
fn write_btf_chart(r: &BtfReport, path: &std::path::Path) -> Result<(), CliError> {
    let cases: Vec<&str> = r.cache_model.iter().map(|c| c.case.as_str()).collect();
    let bar = 14.0;
    let group = bar * 2.0 + 8.0;
    let left = 130.0;
    let panel_w = 360.0;
    let height = 70.0 + group * cases.len() as f64;
    let fps_max = r.timing.rows.iter().map(|x| x.fps_median).fold(1e-9, f64::max);
    let eff_max = r.cache_model.iter().map(|c| c.load_efficiency).filter(|x| x.is_finite()).fold(1e-9, f64::max);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{}' height='{height}' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n\
         <text x='10' y='20' font-size='14'>hitex bench btf ({}): frames per second (left; blue CPU, orange GPU) and load efficiency (right; model, (a) = 1)</text>\n",
        left * 2.0 + panel_w * 2.0 + 40.0,
        r.material
    );
    for (i, case) in cases.iter().enumerate() {
        let y = 40.0 + i as f64 * group;
        s += &format!("<text x='10' y='{:.0}'>{case}</text>\n", y + bar + 4.0);
        for (k, be) in ["cpu", "gpu"].iter().enumerate() {
            if let Some(row) = r.timing.rows.iter().find(|x| x.case == *case && x.backend == *be) {
                let w = panel_w * row.fps_median / fps_max;
                let color = if k == 0 { "#3b7dd8" } else { "#d8703b" };
                let yy = y + k as f64 * bar;
                s += &format!(
                    "<rect x='{left}' y='{yy:.0}' width='{w:.1}' height='{:.0}' fill='{color}'/><text x='{:.1}' y='{:.0}'>{:.0}</text>\n",
                    bar - 2.0,
                    left + w + 4.0,
                    yy + bar - 3.0,
                    row.fps_median
                );
            }
        }
        if let Some(c) = r.cache_model.iter().find(|c| c.case == *case)
            && c.load_efficiency.is_finite()
        {
            let x0 = left * 2.0 + panel_w;
            let w = panel_w * c.load_efficiency / eff_max;
            s += &format!(
                "<rect x='{x0}' y='{:.0}' width='{w:.1}' height='{:.0}' fill='#5aa05a'/><text x='{:.1}' y='{:.0}'>{:.2}</text>\n",
                y + bar / 2.0,
                bar - 2.0,
                x0 + w + 4.0,
                y + bar * 1.5 - 3.0,
                c.load_efficiency
            );
        }
    }
    s += "</svg>\n";
    hitex_io::write_atomic(path, s.as_bytes()).map_err(CliError::from)
}
