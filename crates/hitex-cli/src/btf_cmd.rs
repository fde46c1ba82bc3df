//! `hitex btf …`: synthesise, inspect, import, export and render BTFs.

use crate::progress::Progress;
use crate::{Backend, CliError, open_renderer, parse_size, render_frame, save};
use clap::{Subcommand, ValueEnum};
use glam::Vec3;
use hitex_core::btf::features::features;
use hitex_core::btf::index::{IndexMap, SynthesisOptions, synthesize_index};
use hitex_core::btf::mip::BtfMip;
use hitex_core::btf::pca::{LocalPca, PcaOptions};
use hitex_core::btf::seams::seam_quality;
use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
use hitex_core::btf::{AngularGrid, Btf, Layout};
use hitex_core::scene::Camera;
use hitex_core::texture::ToneMap;
use hitex_core::texture::bc1::Bc1Encoder;
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::{Job, Renderer};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `hitex btf` subcommands.
#[derive(Subcommand)]
pub enum BtfCommand {
    /// Generate a procedural BTF (corduroy, knit, leather, woven, brushed-metal).
    Synth {
        /// Material name.
        material: String,
        /// Output `.hbtf`.
        #[arg(short, long)]
        output: PathBuf,
        /// Sample side in texels (the paper's is 32); `N` or `NxN`.
        #[arg(long, default_value_t = 32, value_parser = parse_side)]
        size: u32,
        /// Polar angles in degrees, comma-separated (default: 0,10,…,70).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        theta: Option<Vec<f32>>,
        /// Azimuth count.
        #[arg(long, default_value_t = 16)]
        phi: usize,
        /// Rays per texel side.
        #[arg(long, default_value_t = 2)]
        supersample: u32,
    },
    /// Describe a `.hbtf` file (or a material, synthesised): grid, sample, sizes of every layout.
    Info {
        /// Input `.hbtf`, or a material name.
        input: String,
    },
    /// Grow a seamless, tileable index map from the BTF's sample.
    Index {
        /// Input `.hbtf` (or a material name, synthesised on the fly).
        input: String,
        /// Index map side in texels; `N` or `NxN`.
        #[arg(long, default_value_t = 128, value_parser = parse_side)]
        size: u32,
        /// Output index map (16-bit PNG: red = sample column, green = sample row).
        #[arg(short, long)]
        output: PathBuf,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Correction passes.
        #[arg(long, default_value_t = 3)]
        passes: u32,
    },
    /// Import a BTF image set (UBO2003/ATRIUM zip or folder, UTIA folder;
    /// PNG/JPEG, or OpenEXR for an HDR BTF).
    Import {
        /// Zip archive or folder.
        input: PathBuf,
        /// Output `.hbtf`.
        #[arg(short, long)]
        output: PathBuf,
        /// Resize the images to SIZE×SIZE texels.
        #[arg(long)]
        size: Option<u32>,
        /// Target polar angles (degrees, comma-separated) for resampling.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        theta: Option<Vec<f32>>,
        /// Target azimuth count for resampling.
        #[arg(long)]
        phi: Option<usize>,
    },
    /// Export a BTF as an image set (one image per view/light pair).
    Export {
        /// Input `.hbtf`.
        input: PathBuf,
        /// Output folder (created; an existing one must be empty).
        #[arg(short, long)]
        output: PathBuf,
        /// File-name convention.
        #[arg(long, value_enum, default_value_t = ConventionArg::Utia)]
        convention: ConventionArg,
        /// Image format: png (8-bit sRGB; an HDR BTF's display copy) or exr
        /// (half-float linear RGB; an HDR BTF's values exactly).
        #[arg(long, value_enum, default_value_t = SetFormatArg::Png)]
        format: SetFormatArg,
    },
    /// Compress a BTF by local PCA into a file every `btf` command reads
    /// (rendered straight from the compressed form).
    Compress {
        /// Input `.hbtf` (or a material name, synthesised on the fly).
        input: String,
        /// Output `.hbtf` (a compressed one).
        #[arg(short, long)]
        output: PathBuf,
        /// CLUSTERS,COMPONENTS: clusters of sample texels, principal
        /// components kept per cluster (e.g. 64,8).
        #[arg(long, value_parser = parse_pca)]
        pca: PcaOptions,
    },
    /// Render a BTF on a surface through one codebook layout.
    Render {
        /// Input `.hbtf`, compressed or not (`btf compress`), or a material
        /// name, synthesised on the fly.
        input: String,
        /// Output PNG.
        #[arg(short, long)]
        output: PathBuf,
        /// Codebook layout: a, b, c, c2, d, e, e2, f.
        #[arg(long, default_value = "f")]
        layout: String,
        /// Compress the codebook with BC1 (DXT1).
        #[arg(long)]
        bc1: bool,
        /// Surface: quad, sphere, torus, teapot, surface (NURBS), or an OBJ mesh.
        #[arg(long, default_value = "quad")]
        on: String,
        /// Index map PNG (default: synthesised, 128×128).
        #[arg(long)]
        index: Option<PathBuf>,
        /// Index-map repeats across the surface.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        repeats: f32,
        /// Light azimuth in degrees around the surface.
        #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
        light_azimuth: f32,
        /// Light elevation in degrees above the surface's plane.
        #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
        light_elevation: f32,
        /// Output size, WIDTHxHEIGHT.
        #[arg(long, value_parser = parse_size, default_value = "640x480")]
        size: (u32, u32),
        /// Which renderer to use.
        #[arg(long, value_enum, default_value_t = Backend::Auto)]
        backend: Backend,
        /// Exposure in stops: the radiance is scaled by 2^STOPS before the
        /// tone map.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        exposure: f32,
        /// Tone map after the exposure: none (clamp at 1), reinhard (x/(1+x)),
        /// aces (Narkowicz's fit); auto is aces for an HDR BTF, none for an
        /// 8-bit one.
        #[arg(long, value_enum, default_value_t = ToneMapArg::Auto)]
        tone_map: ToneMapArg,
        /// MIP mapping: on (a pyramid of index maps with per-level
        /// codebooks, the level chosen per pixel, blended trilinearly), off
        /// (the index map and codebook alone, as the paper renders), or auto:
        /// on when the pyramid's codebook fits the size limits, else off with
        /// a note.
        #[arg(long, value_enum, default_value_t = MipArg::Auto)]
        mip: MipArg,
        /// Compress the codebook by local PCA before rendering:
        /// CLUSTERS,COMPONENTS (e.g. 1,8: one basis of 8 principal
        /// components; each sample texel keeps its cluster and that many
        /// coefficients). Rendered from the compressed form on both
        /// backends; no BC1, no MIP mapping.
        #[arg(long, value_parser = parse_pca)]
        pca: Option<PcaOptions>,
    },
}

/// `CLUSTERS,COMPONENTS` of `--pca`.
pub fn parse_pca(s: &str) -> Result<PcaOptions, String> {
    let (c, k) = s.split_once(',').ok_or_else(|| format!("'{s}' is not CLUSTERS,COMPONENTS (e.g. 1,8)"))?;
    let clusters: usize = c.trim().parse().map_err(|_| format!("clusters '{c}' is not a whole number"))?;
    let components: usize = k.trim().parse().map_err(|_| format!("components '{k}' is not a whole number"))?;
    if clusters == 0 || clusters > hitex_core::btf::pca::MAX_PCA_CLUSTERS {
        return Err(format!("{clusters} clusters; 1..={} are allowed", hitex_core::btf::pca::MAX_PCA_CLUSTERS));
    }
    if components > hitex_core::btf::pca::MAX_PCA_COMPONENTS {
        return Err(format!("{components} components; 0..={} are allowed", hitex_core::btf::pca::MAX_PCA_COMPONENTS));
    }
    Ok(PcaOptions { clusters, components })
}

/// [`hitex_core::btf::pca::fit`] with a progress bar; prints the ratio and
/// the PSNR unless `quiet`.
pub fn pca_with_progress(btf: &Btf, opts: PcaOptions, quiet: bool) -> Result<(LocalPca, f64), CliError> {
    let pb = if quiet { Progress::hidden() } else { bar(0, "local PCA") };
    let t = Instant::now();
    let pca = hitex_core::btf::pca::fit(btf, opts, &|done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })
    .map_err(|e| CliError::Input(e.to_string()))?;
    pb.finish_and_clear();
    let psnr = pca.psnr(btf).map_err(|e| CliError::Internal(e.to_string()))?;
    if !quiet {
        eprintln!(
            "local PCA: {} cluster(s) x {} component(s): {:.2} MiB for {:.2} MiB raw (1:{:.1}), {psnr:.2} dB against the raw texels, fitted in {:.1} s",
            opts.clusters,
            opts.components,
            pca.bytes() as f64 / 1048576.0,
            pca.raw_bytes() as f64 / 1048576.0,
            pca.ratio(),
            t.elapsed().as_secs_f64()
        );
    }
    Ok((pca, psnr))
}

/// MIP mapping of a BTF render.
#[derive(Clone, Copy, ValueEnum, Debug, PartialEq)]
pub enum MipArg {
    /// On where the pyramid fits, else off with a note.
    Auto,
    /// On; an error where the pyramid does not fit.
    On,
    /// Off.
    Off,
}

/// The MIP pyramid of `btf` through `map`, with a progress bar.
pub fn mip_with_progress(btf: &Btf, map: &IndexMap, quiet: bool) -> Result<BtfMip, CliError> {
    let pb = if quiet { Progress::hidden() } else { bar(0, "MIP levels") };
    let mip = hitex_core::btf::mip::build_mip(btf, map, &|done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })
    .map_err(|e| CliError::Input(e.to_string()))?;
    pb.finish_and_clear();
    Ok(mip)
}

/// Tone maps.
#[derive(Clone, Copy, ValueEnum, Debug, PartialEq)]
pub enum ToneMapArg {
    /// aces for an HDR BTF, none for an 8-bit one.
    Auto,
    /// Clamp at 1.
    None,
    /// x / (1 + x).
    Reinhard,
    /// Narkowicz's ACES fit.
    Aces,
}

/// Image-set formats.
#[derive(Clone, Copy, ValueEnum, Debug)]
pub enum SetFormatArg {
    /// 8-bit sRGB PNG.
    Png,
    /// OpenEXR, half-float linear RGB.
    Exr,
}

/// Image-set naming conventions.
#[derive(Clone, Copy, ValueEnum, Debug)]
pub enum ConventionArg {
    /// `tl000 pl000 tv000 pv000.png` (Bonn UBO2003/ATRIUM).
    Ubo,
    /// `tl000_pl000_tv000_pv000.png` (UTIA).
    Utia,
}

pub(crate) fn bar(len: u64, what: &str) -> Progress {
    Progress::new(len, what, "", "{prefix:>12} [{bar:30}] {pos}/{len} {msg} {elapsed}")
}

fn grid_from(theta: Option<Vec<f32>>, phi: usize) -> Result<AngularGrid, CliError> {
    match theta {
        Some(t) => AngularGrid::new(t, phi).map_err(|e| CliError::Input(format!("--theta/--phi: {e}"))),
        None if phi == 16 => Ok(AngularGrid::paper()),
        None => {
            AngularGrid::new((0..8).map(|i| i as f32 * 10.0).collect(), phi).map_err(|e| CliError::Input(e.to_string()))
        }
    }
}

/// Synthesises `material` with a progress bar.
pub fn synth_with_progress(material: Material, opts: &SynthOptions, quiet: bool) -> Result<Btf, CliError> {
    let pb = if quiet { Progress::hidden() } else { bar(opts.grid.directions() as u64, "synth") };
    pb.set_message("view directions");
    let btf =
        synthesize(material, opts, &|done| pb.set_position(done as u64)).map_err(|e| CliError::Input(e.to_string()))?;
    pb.finish_and_clear();
    Ok(btf)
}

/// `mesh` with texture coordinates projected onto the plane of its two
/// longest bounding-box extents (one unit of texture per longest extent).
fn planar_uvs(mesh: &hitex_core::scene::Mesh) -> Result<hitex_core::scene::Mesh, CliError> {
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::INFINITY), glam::Vec3::splat(f32::NEG_INFINITY));
    for p in &mesh.positions {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let ext = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
    let scale = 1.0 / ext[axes[0]].max(f32::MIN_POSITIVE);
    let uvs = mesh
        .positions
        .iter()
        .map(|p| glam::Vec2::new((p[axes[0]] - lo[axes[0]]) * scale, (p[axes[1]] - lo[axes[1]]) * scale))
        .collect();
    hitex_core::scene::Mesh::new(
        &mesh.name,
        mesh.positions.clone(),
        Some(mesh.normals.clone()),
        Some(uvs),
        mesh.indices.clone(),
    )
    .map_err(|e| CliError::Input(e.to_string()))
}

/// A `.hbtf` path (its local PCA too when the file is a compressed one,
/// the BTF then its reconstruction), or a material name synthesised with
/// the paper's defaults.
pub fn load_or_synth_pca(input: &str, quiet: bool) -> Result<(Btf, Option<LocalPca>), CliError> {
    match stored_pca(input)? {
        Some(p) => Ok((hitex_io::btf_pca_file::decompressed(&p, Path::new(input))?, Some(p))),
        None => Ok((load_or_synth(input, quiet)?, None)),
    }
}

/// The local PCA of `input` when it is a compressed `.hbtf` (by its first
/// bytes; a damaged one is refused by name), None for anything else.
pub fn stored_pca(input: &str) -> Result<Option<LocalPca>, CliError> {
    use std::io::Read;
    let path = Path::new(input);
    let mut head = [0u8; 4];
    let compressed = path.is_file()
        && std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head)).is_ok()
        && hitex_io::btf_pca_file::is_pca_file(&head);
    Ok(if compressed { Some(hitex_io::btf_pca_file::read_pca_file(path)?) } else { None })
}

/// A BTF to render: its texels, or the local PCA of a compressed file.
enum Source {
    Raw(Btf),
    Pca(LocalPca),
}

/// A `.hbtf` path, or a material name synthesised with the paper's defaults.
pub fn load_or_synth(input: &str, quiet: bool) -> Result<Btf, CliError> {
    if let Some(m) = Material::parse(input)
        && !Path::new(input).exists()
    {
        return synth_with_progress(m, &SynthOptions::default(), quiet);
    }
    Ok(hitex_io::btf_file::read_hbtf(Path::new(input))?)
}

/// Grows an index map with a progress bar.
pub fn index_with_progress(btf: &Btf, size: u32, seed: u64, passes: u32, quiet: bool) -> Result<IndexMap, CliError> {
    let opts = SynthesisOptions { width: size, height: size, seed, passes, ..Default::default() };
    let pb = if quiet { Progress::hidden() } else { bar(passes as u64, "index") };
    pb.set_message("passes");
    let map =
        synthesize_index(btf, &opts, &|p, _| pb.set_position(p as u64)).map_err(|e| CliError::Input(e.to_string()))?;
    pb.finish_and_clear();
    Ok(map)
}

/// Writes an index map as a 16-bit RGB PNG: red = sample column, green = sample row.
pub fn save_index(map: &IndexMap, path: &Path) -> Result<(), CliError> {
    let mut data: Vec<u16> = Vec::with_capacity(map.entries.len() * 3);
    for e in &map.entries {
        data.extend_from_slice(&[e[0], e[1], 0]);
    }
    let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(map.width, map.height, data)
        .ok_or_else(|| CliError::Internal("index map buffer has the wrong size".into()))?;
    if crate::image_out(path)? != crate::ImageOut::Png {
        return Err(CliError::Input(format!(
            "{}: an index map is written as a 16-bit PNG: name it .png",
            path.display()
        )));
    }
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)
        .map_err(|e| CliError::Internal(format!("{}: {e}", path.display())))?;
    hitex_io::write_atomic(path, buf.get_ref()).map_err(CliError::from)
}

/// Reads an index map PNG written by [`save_index`] (8- or 16-bit), checking
/// every entry against the sample size.
pub fn load_index(path: &Path, sample: (u32, u32)) -> Result<IndexMap, CliError> {
    let img = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?
        .decode()
        .map_err(|e| CliError::Input(format!("{}: not a readable image: {e}", path.display())))?
        .into_rgb16();
    let (w, h) = img.dimensions();
    let mut entries = Vec::with_capacity((w * h) as usize);
    for (i, p) in img.pixels().enumerate() {
        // 8-bit files are widened ×257 by the decoder
        let (u, v) = if img.as_raw().iter().all(|c| c % 257 == 0) && sample.0 <= 256 {
            (p[0] / 257, p[1] / 257)
        } else {
            (p[0], p[1])
        };
        if u as u32 >= sample.0 || v as u32 >= sample.1 {
            return Err(CliError::Input(format!(
                "{}: texel {} names sample texel ({u}, {v}) outside the {}x{} sample",
                path.display(),
                i,
                sample.0,
                sample.1
            )));
        }
        entries.push([u, v]);
    }
    Ok(IndexMap { width: w, height: h, entries })
}

/// The surface to render on.
pub fn surface_for(on: &str, repeats: f32) -> Result<BtfSurface, CliError> {
    use hitex_core::scene::Mesh;
    Ok(match on {
        "quad" => BtfSurface::quad(2.0, repeats),
        "sphere" => BtfSurface::from_mesh(&Mesh::sphere(64, 32), repeats),
        "torus" => BtfSurface::from_mesh(&Mesh::torus(0.35, 96, 48), repeats),
        "teapot" | "surface" => {
            let model = hitex_io::models::load_model(on)?;
            let surfaces: Vec<_> = model.surfaces.iter().map(|s| s.surface.clone()).collect();
            BtfSurface::from_nurbs(&surfaces, 24, repeats)
        }
        path if path.ends_with(".obj") => {
            let meshes = hitex_io::load_obj(Path::new(path))?;
            let mut s = BtfSurface::default();
            for m in meshes {
                // a mesh without texture coordinates would show one texel:
                // it gets a planar projection, and the user is told
                let m = if m.uvs.iter().all(|t| *t == m.uvs[0]) {
                    eprintln!(
                        "hitex: warning: {}: no texture coordinates (vt): the BTF is projected onto the plane of \
                         the mesh's two longest extents",
                        m.name
                    );
                    planar_uvs(&m)?
                } else {
                    m
                };
                let part = BtfSurface::from_mesh(&m, repeats);
                let base = s.vertices.len() as u32;
                s.vertices.extend(part.vertices);
                s.indices.extend(part.indices.iter().map(|i| i + base));
            }
            s
        }
        other => {
            return Err(CliError::Input(format!(
                "unknown surface '{other}': use quad, sphere, torus, teapot, surface or a .obj file"
            )));
        }
    })
}

/// A camera framing `surface` from the front-right, above, for an output of
/// aspect ratio `aspect` (width / height).
pub fn camera_for(surface: &BtfSurface, quad: bool, aspect: f32) -> Result<Camera, CliError> {
    let (c, r) = surface.bounds();
    let dir = if quad { Vec3::new(0.0, -0.55, 1.0).normalize() } else { Vec3::new(0.8, -1.6, 0.9).normalize() };
    let fov: f32 = 35.0;
    // the narrower of the two fields of view decides
    let half = (fov.to_radians() / 2.0).tan();
    let narrow = (half * aspect.clamp(0.1, 10.0).min(1.0)).atan();
    let dist = r / narrow.sin() * if quad { 1.05 } else { 0.8 };
    let up = if quad { Vec3::Y } else { Vec3::Z };
    Camera::new(c + dir * dist, c, up, fov, dist * 0.05, dist * 4.0).map_err(|e| CliError::Input(e.to_string()))
}

/// The light position at `azimuth`/`elevation` (degrees) around `surface`.
pub fn light_for(surface: &BtfSurface, quad: bool, azimuth: f32, elevation: f32) -> Vec3 {
    let (c, r) = surface.bounds();
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    let d = if quad {
        Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
    } else {
        Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()).normalize()
    };
    c + d * (r * 6.0)
}

fn parse_layout(s: &str) -> Result<Layout, CliError> {
    Layout::parse(s).ok_or_else(|| {
        let names: Vec<&str> = Layout::ALL.iter().map(|l| l.name()).collect();
        CliError::Input(format!("unknown layout '{s}': use one of {}", names.join(", ")))
    })
}

/// A square side: `N`, or `NxN` as the renders' `--size WxH` (sides must match).
fn parse_side(s: &str) -> Result<u32, String> {
    let one = |t: &str| t.trim().parse::<u32>().map_err(|_| format!("'{t}' is not a whole number of texels"));
    match s.split_once(['x', 'X']) {
        Some((a, b)) => {
            let (a, b) = (one(a)?, one(b)?);
            if a != b {
                return Err(format!("{s}: the sample and index maps are square: give one side, e.g. {a}"));
            }
            Ok(a)
        }
        None => one(s),
    }
}

/// Runs a `hitex btf` subcommand.
pub fn run(cmd: BtfCommand) -> Result<(), CliError> {
    match cmd {
        BtfCommand::Synth { material, output, size, theta, phi, supersample } => {
            let m = Material::parse(&material).ok_or_else(|| {
                let names: Vec<_> = Material::ALL.iter().map(|m| m.name()).collect();
                CliError::Input(format!("unknown material '{material}': use one of {}", names.join(", ")))
            })?;
            if !(1..=1024).contains(&size) {
                return Err(CliError::Input(format!("--size {size} must be in 1 to 1024 texels")));
            }
            if !(1..=256).contains(&phi) {
                return Err(CliError::Input(format!("--phi {phi} must be in 1 to 256 azimuths")));
            }
            if !(1..=16).contains(&supersample) {
                return Err(CliError::Input(format!(
                    "--supersample {supersample} must be in 1 to 16 rays per texel side"
                )));
            }
            if !output.extension().is_some_and(|e| e.eq_ignore_ascii_case("hbtf")) {
                return Err(CliError::Input(format!(
                    "-o {}: a synthesised BTF is written as .hbtf (btf export writes image sets)",
                    output.display()
                )));
            }
            let grid = grid_from(theta, phi)?;
            // every (view, light) image of size² texels: bounded before any work
            let d = grid.directions() as u64;
            let limit = hitex_core::btf::dataset::MAX_BTF_TEXELS;
            if d * d * size as u64 * size as u64 > limit {
                let most = ((limit / (d * d)) as f64).sqrt().floor() as u64;
                return Err(CliError::Input(format!(
                    "--size {size}: {d}×{d} (view, light) images of {size}x{size} texels exceed the limit of \
                     {limit} texels; at most --size {most} with this grid (fewer --theta or --phi allow more)"
                )));
            }
            let opts = SynthOptions { grid, size, supersample, ..Default::default() };
            let t = Instant::now();
            let btf = synth_with_progress(m, &opts, false)?;
            let secs = t.elapsed().as_secs_f64();
            hitex_io::btf_file::write_hbtf(&output, &btf)?;
            say!(
                "wrote {}: {} {} images of {}x{} texels ({:.1} MiB as RGBA8) in {secs:.2} s",
                output.display(),
                btf.images(),
                m.name(),
                btf.width(),
                btf.height(),
                btf.gpu_bytes() as f64 / (1 << 20) as f64
            );
            Ok(())
        }
        BtfCommand::Info { input } => {
            let (btf, pca) = load_or_synth_pca(&input, true)?;
            let g = btf.grid();
            say!("{input}");
            say!("  sample: {}x{} texels", btf.width(), btf.height());
            if let Some(p) = &pca {
                say!(
                    "  compressed: local PCA, {} cluster{} × {} component{}, {:.2} MiB for {:.2} MiB of {} texels (1:{:.1}); \
                     what follows describes its reconstruction",
                    p.clusters(),
                    if p.clusters() == 1 { "" } else { "s" },
                    p.components(),
                    if p.components() == 1 { "" } else { "s" },
                    p.bytes() as f64 / 1048576.0,
                    p.raw_bytes() as f64 / 1048576.0,
                    if p.is_hdr() { "half-float" } else { "8-bit" },
                    p.ratio()
                );
            }
            match btf.hdr() {
                Some(h) => {
                    let max = h.half.iter().map(|&v| hitex_core::btf::dataset::half_value(v)).fold(0.0, f32::max);
                    say!(
                        "  texels: HDR, linear RGB half floats up to {max}; 8-bit display copy scaled by {:.4}",
                        h.ldr_scale
                    );
                }
                None => say!("  texels: 8-bit sRGB"),
            }
            say!(
                "  grid: θ = {:?}° ({}), φ: {} × {:.2}°; {} view × {} light directions, {} images",
                g.theta_deg(),
                g.theta_count(),
                g.phi_count(),
                360.0 / g.phi_count() as f32,
                g.directions(),
                g.directions(),
                btf.images()
            );
            if btf.is_hdr() {
                say!(
                    "  codebook: {:.1} MiB as RGBA16F (BC1 holds 8-bit colours only)",
                    2.0 * btf.gpu_bytes() as f64 / 1048576.0
                );
            } else {
                say!(
                    "  codebook: {:.1} MiB as RGBA8, {:.1} MiB as BC1",
                    btf.gpu_bytes() as f64 / 1048576.0,
                    btf.gpu_bytes() as f64 / 8.0 / 1048576.0
                );
            }
            say!("  layouts:");
            for l in Layout::ALL {
                match hitex_core::btf::Codebook::build(&btf, l) {
                    Ok(cb) => say!(
                        "    {:<5} (--layout {:<2}) {:>5}x{:<5}x{:<3} texels, tiles {}x{}, {:>3} reads/pixel, {:.1} MiB",
                        l.label(),
                        l.name(),
                        cb.width,
                        cb.height,
                        cb.depth,
                        cb.tile_w,
                        cb.tile_h,
                        l.codebook_reads(),
                        (if cb.is_hdr() { 8 * cb.half.len() as u64 } else { cb.bytes() }) as f64 / 1048576.0
                    ),
                    Err(e) => say!("    {:<5} (--layout {:<2}) not possible: {e}", l.label(), l.name()),
                }
            }
            Ok(())
        }
        BtfCommand::Index { input, size, output, seed, passes } => {
            crate::image_out(&output)?;
            if !(1..=8192).contains(&size) {
                return Err(CliError::Input(format!("--size {size} must be in 1 to 8192 texels")));
            }
            let btf = load_or_synth(&input, false)?;
            let t = Instant::now();
            let map = index_with_progress(&btf, size, seed, passes, false)?;
            let secs = t.elapsed().as_secs_f64();
            save_index(&map, &output)?;
            let feats = features(&btf, 8);
            let q = seam_quality(&btf, &map, &feats);
            // preview: the u/v colours beside the frontal appearance through the map
            let preview = output.with_file_name(format!(
                "{}-preview.png",
                output.file_stem().and_then(|s| s.to_str()).unwrap_or("index")
            ));
            save(&index_preview(&btf, &map), &preview)?;
            say!(
                "wrote {} ({size}x{size}, 16-bit sample coordinates: dark in an image viewer, see the preview) in {secs:.2} s; seam score (mean feature distance to the coherent continuation): interior {:.4}, across the wrap edges {:.4} (ratio {:.2}; ≤ 1 means the tiling seam is invisible); preview {}",
                output.display(),
                q.interior_error,
                q.seam_error,
                q.ratio,
                preview.display()
            );
            Ok(())
        }
        BtfCommand::Import { input, output, size, theta, phi } => {
            crate::file_output(&output, &["hbtf"], "an imported BTF")?;
            if let Some(s) = size
                && !(1..=hitex_core::btf::dataset::MAX_BTF_SIDE).contains(&s)
            {
                return Err(CliError::Input(format!(
                    "--size {s} must be in 1 to {} texels",
                    hitex_core::btf::dataset::MAX_BTF_SIDE
                )));
            }
            let grid = match (theta, phi) {
                (None, None) => None,
                (t, p) => Some(grid_from(t, p.unwrap_or(16))?),
            };
            let pb = bar(0, "import");
            pb.set_message("images");
            let (btf, report) = hitex_io::btf_images::import_image_set(&input, grid, size, &|done, total| {
                pb.set_length(total as u64);
                pb.set_position(done as u64);
            })?;
            pb.finish_and_clear();
            hitex_io::btf_file::write_hbtf(&output, &btf)?;
            say!(
                "wrote {}: {} images read ({} view × {} light directions), {}x{} texels, grid {}×{}{}",
                output.display(),
                report.images,
                report.view_dirs,
                report.light_dirs,
                btf.width(),
                btf.height(),
                btf.grid().theta_count(),
                btf.grid().phi_count(),
                if report.resampled { format!("; {}", report.method) } else { String::new() }
            );
            // a set far sparser than its grid is filled by resampling: said, not hidden
            let d = btf.grid().directions();
            for (what, n) in [("view", report.view_dirs), ("light", report.light_dirs)] {
                if report.resampled && n * 4 < d {
                    eprintln!(
                        "hitex: warning: {}: the images hold {} but the grid has {d}: \
                         the others are resampled from {}; give --theta/--phi for the set's own grid",
                        input.display(),
                        crate::count(n, &format!("{what} direction"), &format!("{what} directions")),
                        if n == 1 { "that one" } else { "those" }
                    );
                }
            }
            if let Some(h) = btf.hdr() {
                say!(
                    "  HDR: OpenEXR values kept as half floats (version 2 file); the 8-bit display copy is scaled by {:.4}",
                    h.ldr_scale
                );
            }
            if report.clamped > 0 {
                say!(
                    "  clamped: {} EXR values were NaN, infinite, negative or outside the sRGB gamut, set into [0, 65504] \
                     (first in {})",
                    report.clamped,
                    report.clamped_first.as_deref().unwrap_or("?")
                );
            }
            for (what, list) in
                [("missing", &report.missing), ("duplicated", &report.duplicated), ("ignored", &report.ignored)]
            {
                if !list.is_empty() {
                    let shown: Vec<_> = list.iter().take(8).cloned().collect();
                    say!("  {what}: {} ({}{})", list.len(), shown.join(", "), if list.len() > 8 { ", …" } else { "" });
                }
            }
            Ok(())
        }
        BtfCommand::Export { input, output, convention, format } => {
            crate::folder_output(&output, "btf export (an image set)")?;
            let btf = load_or_synth(&input.to_string_lossy(), false)?;
            let conv = match convention {
                ConventionArg::Ubo => hitex_io::btf_images::Convention::Ubo,
                ConventionArg::Utia => hitex_io::btf_images::Convention::Utia,
            };
            if let Ok(mut entries) = std::fs::read_dir(&output)
                && entries.next().is_some()
            {
                return Err(CliError::Input(format!(
                    "{}: the folder is not empty; export into a new or empty folder so that two image sets never mix",
                    output.display()
                )));
            }
            let g = btf.grid();
            let total = (g.directions() * g.directions()) as u64;
            let pb = bar(total, "export");
            pb.set_message("images");
            let fmt = match format {
                SetFormatArg::Png => hitex_io::btf_images::SetFormat::Png,
                SetFormatArg::Exr => hitex_io::btf_images::SetFormat::Exr,
            };
            let n = hitex_io::btf_images::export_image_set_as(&btf, &output, conv, fmt, &mut |done, _| {
                pb.set_position(done as u64)
            })?;
            pb.finish_and_clear();
            let what = match (fmt, btf.hdr()) {
                (hitex_io::btf_images::SetFormat::Png, Some(h)) => format!(
                    "8-bit PNG of the HDR BTF's display copy (linear values × {:.4}); --format exr keeps the values",
                    h.ldr_scale
                ),
                (hitex_io::btf_images::SetFormat::Png, None) => "8-bit PNG".into(),
                (hitex_io::btf_images::SetFormat::Exr, Some(_)) => "OpenEXR, the half-float values exactly".into(),
                (hitex_io::btf_images::SetFormat::Exr, None) => "OpenEXR, the 8-bit texels decoded to linear".into(),
            };
            say!("wrote {n} images to {} ({what})", output.display());
            Ok(())
        }
        BtfCommand::Compress { input, output, pca } => {
            if stored_pca(&input)?.is_some() {
                return Err(CliError::Input(format!(
                    "{input} is already compressed by local PCA: compress the BTF it was made from"
                )));
            }
            let btf = load_or_synth(&input, false)?;
            let (p, _) = pca_with_progress(&btf, pca, false)?;
            hitex_io::btf_pca_file::write_pca_file(&output, &p)?;
            let len = std::fs::metadata(&output).map(|m| m.len()).unwrap_or(0);
            say!(
                "wrote {} ({:.2} MiB; `btf render` draws it from the basis, every other `btf` command from its \
                 reconstruction)",
                output.display(),
                len as f64 / 1048576.0
            );
            Ok(())
        }
        BtfCommand::Render {
            input,
            output,
            layout,
            bc1,
            on,
            index,
            repeats,
            light_azimuth,
            light_elevation,
            size,
            backend,
            exposure,
            tone_map,
            mip,
            pca,
        } => {
            crate::image_out(&output)?;
            if pca.is_some() && bc1 {
                return Err(CliError::Input(
                    "--pca and --bc1 exclude each other: the PCA basis is half floats, which BC1 cannot hold".into(),
                ));
            }
            if pca.is_some() && mip == MipArg::On {
                return Err(CliError::Input(
                    "--pca renders without MIP mapping (the PCA of MIP levels is not built); use --mip off or auto"
                        .into(),
                ));
            }
            if !(exposure.is_finite() && exposure.abs() <= 64.0) {
                return Err(CliError::Input(format!("--exposure {exposure} must be in [-64, 64] stops")));
            }
            if !(repeats.is_finite() && repeats > 0.0 && repeats <= 1000.0) {
                return Err(CliError::Input(format!("--repeats {repeats} must be in (0, 1000]")));
            }
            if !light_azimuth.is_finite() {
                return Err(CliError::Input(format!("--light-azimuth {light_azimuth} must be finite (degrees)")));
            }
            if !(light_elevation.is_finite() && light_elevation > 0.0 && light_elevation <= 90.0) {
                return Err(CliError::Input(format!(
                    "--light-elevation {light_elevation} must be in (0, 90] degrees above the surface"
                )));
            }
            let layout = parse_layout(&layout)?;
            let stored = stored_pca(&input)?;
            if stored.is_some() && pca.is_some() {
                return Err(CliError::Input(format!(
                    "{input} is already compressed by local PCA: drop --pca to render it as it is"
                )));
            }
            if stored.is_some() && (bc1 || mip == MipArg::On) {
                return Err(CliError::Input(format!(
                    "{input} is compressed by local PCA, rendered without BC1 and without MIP mapping: drop {}",
                    if bc1 { "--bc1" } else { "--mip on" }
                )));
            }
            // a compressed file is drawn from its basis: reconstructed only to grow an index map
            let source = match stored {
                Some(p) => Source::Pca(p),
                None => Source::Raw(load_or_synth(&input, false)?),
            };
            let (sample, hdr) = match &source {
                Source::Raw(b) => ((b.width(), b.height()), b.is_hdr()),
                Source::Pca(p) => ((p.width(), p.height()), p.is_hdr()),
            };
            let map = match (index, &source) {
                (Some(p), _) => load_index(&p, sample)?,
                (None, Source::Raw(btf)) => index_with_progress(btf, 128, 1, 3, false)?,
                (None, Source::Pca(p)) => {
                    let btf = hitex_io::btf_pca_file::decompressed(p, Path::new(&input))?;
                    index_with_progress(&btf, 128, 1, 3, false)?
                }
            };
            let surface = surface_for(&on, repeats)?;
            let quad = on == "quad";
            let camera = camera_for(&surface, quad, size.0 as f32 / size.1 as f32)?;
            let light = light_for(&surface, quad, light_azimuth, light_elevation);
            let t = Instant::now();
            let enc = bc1.then_some(Bc1Encoder::Ispc);
            let with_mip = |btf: &Btf, surface: BtfSurface| -> Result<(PreparedBtf, String), CliError> {
                let m = mip_with_progress(btf, &map, false)?;
                let note = format!(
                    ", MIP {} levels ({} entries over the coarser levels; twice the reads where two levels blend)",
                    m.level_count(),
                    m.entries[1..].iter().sum::<usize>(),
                );
                Ok((PreparedBtf::with_mip(&m, layout, enc, surface)?, note))
            };
            let (mut prepared, mip_note) = match (&source, pca, mip) {
                (Source::Pca(p), _, _) => {
                    let note = format!(
                        ", local PCA {}x{} read from the file (1:{:.1}; {} basis images read per cluster), without MIP",
                        p.clusters(),
                        p.components(),
                        p.ratio(),
                        p.components() + 1
                    );
                    (PreparedBtf::with_pca(p, layout, map.clone(), surface)?, note)
                }
                (Source::Raw(btf), Some(opts), _) => {
                    let (pca, psnr) = pca_with_progress(btf, opts, false)?;
                    let note = format!(
                        ", local PCA {}x{} (1:{:.1}, {psnr:.1} dB; {} basis images read per cluster), without MIP",
                        opts.clusters,
                        opts.components,
                        pca.ratio(),
                        opts.components + 1
                    );
                    (PreparedBtf::with_pca(&pca, layout, map.clone(), surface)?, note)
                }
                (Source::Raw(btf), None, MipArg::Off) => {
                    (PreparedBtf::new(btf, layout, enc, map.clone(), surface)?, String::new())
                }
                (Source::Raw(btf), None, MipArg::On) => with_mip(btf, surface)?,
                (Source::Raw(btf), None, MipArg::Auto) => match with_mip(btf, surface.clone()) {
                    Ok(p) => p,
                    // a pyramid that does not fit; anything else is an error
                    Err(CliError::Input(e)) => {
                        eprintln!("hitex: rendering without MIP mapping ({e}); --mip off says so quietly");
                        (PreparedBtf::new(btf, layout, enc, map.clone(), surface)?, ", without MIP".into())
                    }
                    Err(e) => return Err(e),
                },
            };
            let prep_ms = t.elapsed().as_secs_f64() * 1e3;
            prepared.exposure = exposure.exp2();
            prepared.tone_map = match tone_map {
                ToneMapArg::Auto if hdr => ToneMap::Aces,
                ToneMapArg::Auto | ToneMapArg::None => ToneMap::None,
                ToneMapArg::Reinhard => ToneMap::Reinhard,
                ToneMapArg::Aces => ToneMap::Aces,
            };
            let mut r = open_renderer(backend)?;
            let t = Instant::now();
            let frame = render_frame(&mut r, &Job::Btf { surface: &prepared, camera, light }, size)?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            save(&frame, &output)?;
            let tone = if hdr || exposure != 0.0 || prepared.tone_map != ToneMap::None {
                format!(
                    ", {} texels, exposure {exposure:+} stops, tone map {}",
                    if hdr { "HDR half-float" } else { "8-bit" },
                    prepared.tone_map.name()
                )
            } else {
                String::new()
            };
            // a PCA pixel reads its k + 1 basis images per cluster among its four index texels
            let components = match &source {
                Source::Pca(p) => Some(p.components() as usize),
                Source::Raw(_) => pca.map(|o| o.components),
            };
            let reads = match components {
                Some(k) => format!(
                    "{} codebook reads per pixel and cluster among its index texels",
                    layout.codebook_reads() as usize * (k + 1) / 4
                ),
                None => format!("{} codebook reads per pixel", layout.codebook_reads()),
            };
            say!(
                "wrote {} ({}x{}, layout {}{}{tone}{mip_note}, {reads}, {}) in {ms:.1} ms (+{prep_ms:.0} ms layout{})",
                output.display(),
                size.0,
                size.1,
                layout.label(),
                if bc1 { " BC1" } else { "" },
                r.name(),
                if bc1 {
                    " + BC1"
                } else if pca.is_some() {
                    " + PCA fit"
                } else {
                    ""
                }
            );
            Ok(())
        }
    }
}

/// The index map's u/v colours beside the frontal appearance (view and light
/// at θ = 0) of the BTF read through it.
pub fn index_preview(btf: &Btf, map: &IndexMap) -> hitex_render::Frame {
    let (w, h) = (map.width, map.height);
    let uv = map.to_rgba(btf.width(), btf.height());
    let mut rgba = vec![0u8; (2 * w * h * 4) as usize];
    let img = btf.image(0, 0);
    for y in 0..h {
        for x in 0..w {
            let o = ((y * 2 * w + x) * 4) as usize;
            let i = ((y * w + x) * 4) as usize;
            rgba[o..o + 4].copy_from_slice(&uv[i..i + 4]);
            let e = map.get(x, y);
            let s = ((e[1] as u32 * btf.width() + e[0] as u32) * 3) as usize;
            let o2 = o + (w * 4) as usize;
            rgba[o2..o2 + 4].copy_from_slice(&[img[s], img[s + 1], img[s + 2], 255]);
        }
    }
    hitex_render::Frame { width: 2 * w, height: h, rgba }
}
