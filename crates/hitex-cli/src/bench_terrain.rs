//! `hitex bench terrain`: the same flight frames over a GST store on both
//! backends through the resident-map cache, per-pixel trilinear and the
//! span-parallel samplers of eq. (8)–(10) (3×3 banks, 4×4 banks, bicubic),
//! with each span sampler's image difference against trilinear and its
//! bank traffic (recorded by the CPU backend's bank model).

use crate::bench::{Backends, CaseFn, Report, print_table, run_case_fns};
use crate::terrain_store_cmd::{flight_area, frame_setup, open_cache};
use crate::{CliError, parse_size};
use hitex_core::terrain::path::PathKey;
use hitex_core::texture::span::{BankModel, psnr, ssim};
use hitex_io::gst::{BuildOptions, ProceduralSource, StoreMeta, TILE, TileSource, build_store};
use hitex_render::cpu::terrain::render_fly;
use hitex_render::terrain::flight::FlightArea;
use hitex_render::terrain::{FlyGround, FlySampler};
use serde::Serialize;
use std::cell::RefCell;
use std::time::Instant;

/// Arguments of `hitex bench terrain`.
#[derive(clap::Args, Debug)]
pub struct TerrainArgs {
    /// Print JSON on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Frames of the orbit.
    #[arg(long, default_value_t = 12)]
    pub frames: u32,
    /// Frame size.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Side of the procedural source in texels (a power of two of at least 256).
    #[arg(long, default_value_t = 4096)]
    pub source: u32,
    /// Backends to run.
    #[arg(long, value_enum, default_value_t = Backends::Both)]
    pub backends: Backends,
    #[command(flatten)]
    pub simd: crate::bench::SimdArg,
}

/// A span case against per-pixel trilinear on the same views.
#[derive(Debug, Clone, Serialize)]
pub struct SpanRow {
    /// Case name.
    pub case: String,
    /// Mean PSNR against per-pixel trilinear, dB.
    pub psnr_db: f64,
    /// Mean SSIM against per-pixel trilinear.
    pub ssim: f64,
    /// Bank conflicts over the whole flight.
    pub bank_conflicts: u64,
    /// Span accesses over the whole flight.
    pub accesses: u64,
    /// Mean λ read (levels below the finest).
    pub mean_level: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct TerrainReport {
    /// Frame timings as every bench.
    #[serde(flatten)]
    pub timing: Report,
    /// Source side in texels.
    pub source: u32,
    /// Maps in the store.
    pub store_maps: u64,
    /// Most maps resident at once during the flight.
    pub resident_maps: usize,
    /// Bytes of those maps.
    pub resident_bytes: usize,
    /// Span cases.
    pub spans: Vec<SpanRow>,
}

/// `hitex bench terrain`.
pub fn terrain(a: TerrainArgs) -> Result<(), CliError> {
    let levels = a.simd.levels()?;
    if a.source < TILE || !a.source.is_power_of_two() || a.source > 16384 {
        return Err(CliError::Input(format!("--source {} must be a power of two in 256 to 16384", a.source)));
    }
    let (w, h) = a.size;
    let dir = std::env::temp_dir().join(format!("hitex-bench-terrain-{}", std::process::id()));
    let src = ProceduralSource { width: a.source, height: a.source, seed: 1 };
    let meta = StoreMeta::for_source(a.source, a.source, [0.0, 0.0], [1.0, 1.0], "", &src.describe());
    let t = Instant::now();
    build_store(&src, &meta, &dir, BuildOptions::default(), &|_, _| {})?;
    if !a.json {
        say!(
            "hitex bench terrain: {} ({} maps, built in {:.1} s), {w}x{h}, an orbit of {} frames at 800 m, pitch 30° below the horizon, FOV 45°",
            src.describe(),
            meta.total_tiles(),
            t.elapsed().as_secs_f64(),
            a.frames
        );
    }
    // the data's extent is the source's: a.source texels a side
    let area = FlightArea { extent: [a.source as f64; 2], ..flight_area(&meta) };
    let frames = a.frames.max(1);
    let key = |i: u32| {
        let ang = i as f64 / frames as f64 * std::f64::consts::TAU;
        PathKey {
            t: i as f64,
            x: 0.5 - 0.3 * ang.sin(),
            y: 0.5 + 0.3 * ang.cos(),
            altitude: 800.0,
            pitch: 30.0,
            heading: ang.to_degrees(),
        }
    };
    let per_side = hitex_core::terrain::active_area(45.0, w, TILE, meta.levels)
        .map_err(|e| CliError::Input(e.to_string()))?
        .first()
        .map_or(6, |l| l.per_side);
    // load every map the flight needs first: the timed frames then measure rendering only
    let budget = (meta.total_tiles() as usize).max(1);
    let cache = RefCell::new(open_cache(std::sync::Arc::new(hitex_io::gst::Store::open(&dir)?), budget)?);
    let mut resident = (0usize, 0usize);
    for i in 0..frames {
        let mut start = Instant::now();
        let (s, _, _) = frame_setup(
            &mut cache.borrow_mut(),
            &meta,
            &area.camera_at(&key(i), 45.0),
            (w, h),
            45.0,
            per_side,
            true,
            &mut start,
        );
        resident = (resident.0.max(s.resident), resident.1.max(s.bytes));
    }
    // one case per sampler, the same frames through the same page tables on both backends
    let case = |sampler: FlySampler| -> CaseFn {
        let (cache, meta, key, area) = (&cache, &meta, &key, &area);
        Box::new(move |i, _k, w, h| {
            let mut start = Instant::now();
            let cam = area.camera_at(&key(i), 45.0);
            let (_, u, pages) =
                frame_setup(&mut cache.borrow_mut(), meta, &cam, (w, h), 45.0, per_side, false, &mut start);
            // rendering only: the bank traffic is measured below
            Ok(hitex_render::Job::Flight {
                uniform: u.with_sampler(sampler),
                pages: std::borrow::Cow::Owned(pages),
                ground: FlyGround::Flat,
                stats: false,
            })
        })
    };
    let cases: Vec<(String, CaseFn)> = FlySampler::ALL.iter().map(|&s| (s.name().to_string(), case(s))).collect();
    let timing = run_case_fns("terrain", &cases, frames, a.size, a.backends, &levels, a.json)?;
    // quality and bank traffic of every span sampler against per-pixel
    // trilinear, on the CPU (which models the banks), over the same frames
    let mut acc: Vec<(f64, f64, BankModel)> = Vec::new();
    for i in 0..frames {
        let mut start = Instant::now();
        let cam = area.camera_at(&key(i), 45.0);
        let (_, u, pages) =
            frame_setup(&mut cache.borrow_mut(), &meta, &cam, (w, h), 45.0, per_side, false, &mut start);
        let reference = render_fly(&u, &pages, FlyGround::Flat)?.frame;
        for (k, s) in FlySampler::ALL[1..].iter().enumerate() {
            let f = render_fly(&u.with_sampler(*s), &pages, FlyGround::Flat)?;
            let banks = f.banks.unwrap_or_default();
            let f = f.frame;
            if acc.len() <= k {
                acc.push((0.0, 0.0, BankModel::default()));
            }
            acc[k].0 += psnr(&reference, &f);
            acc[k].1 += ssim(&reference, &f);
            acc[k].2.merge(banks);
        }
    }
    let spans: Vec<SpanRow> = FlySampler::ALL[1..]
        .iter()
        .zip(acc)
        .map(|(s, (p, q, banks))| SpanRow {
            case: s.name().into(),
            psnr_db: p / frames as f64,
            ssim: q / frames as f64,
            bank_conflicts: banks.conflicts,
            accesses: banks.accesses,
            mean_level: banks.mean_level(),
        })
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    let report = TerrainReport {
        timing,
        source: a.source,
        store_maps: meta.total_tiles(),
        resident_maps: resident.0,
        resident_bytes: resident.1,
        spans,
    };
    if a.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| CliError::Internal(e.to_string()))?;
        say!("{text}");
    } else {
        print_table(&report.timing);
        say!(
            "resident: at most {} maps ({:.1} MiB) of the store's {}",
            report.resident_maps,
            report.resident_bytes as f64 / 1048576.0,
            report.store_maps
        );
        say!(
            "{:<10} {:>10} {:>8} {:>15} {:>12} {:>11}",
            "case",
            "PSNR dB",
            "SSIM",
            "bank conflicts",
            "accesses",
            "mean level"
        );
        for s in &report.spans {
            say!(
                "{:<10} {:>10.2} {:>8.4} {:>15} {:>12} {:>11.2}",
                s.case,
                s.psnr_db,
                s.ssim,
                s.bank_conflicts,
                s.accesses,
                s.mean_level
            );
        }
    }
    Ok(())
}
