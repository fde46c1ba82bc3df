//! `hitex`: the command-line tool.

/// `println!` for every line the tool prints on stdout: a failed write
/// (a full disk, a closed descriptor) is remembered, not a panic, and ends
/// the run with exit 1 and one line ([`stdout_status`]); a reader that went
/// away (`| head`) ends it quietly (SIGPIPE), or, once
/// [`keep_going_on_closed_stdout`] has run, loses the remaining lines but
/// not the files being written.
macro_rules! say {
    () => {
        $crate::write_stdout(format_args!("\n"))
    };
    ($($t:tt)*) => {
        $crate::write_stdout(format_args!("{}\n", format_args!($($t)*)))
    };
}

/// `print!` with [`say!`]'s handling of failed writes.
macro_rules! say_part {
    ($($t:tt)*) => {
        $crate::write_stdout(format_args!($($t)*))
    };
}

mod bench;
mod bench_btf;
mod bench_terrain;
mod btf_cmd;
mod demo;
mod nurbs_cmd;
mod progress;
mod terrain_cmd;
mod terrain_store_cmd;
#[cfg(feature = "viewer")]
mod view;

use clap::{Parser, Subcommand};
use hitex_core::scene::RenderMode;
use hitex_render::{AnyRenderer, BackendChoice, Frame, Job, OpenOptions, PreparedScene, RenderError, Renderer};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// High-fidelity texture mapping and exact surface rendering.
#[derive(Parser)]
#[command(name = "hitex", version, about, long_about = None)]
struct Cli {
    /// Largest allocation any input file may ask for (e.g. 512M, 2G; default
    /// 8G or HITEX_MAX_MEMORY): files claiming more are refused before reading.
    #[arg(long, global = true, value_name = "BYTES", value_parser = hitex_io::limits::parse_bytes)]
    max_memory: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render the embedded showcase (no files needed) into a folder.
    Demo {
        /// Output folder.
        #[arg(short, long, default_value = "out")]
        out: PathBuf,
        /// Which renderer to use.
        #[arg(long, value_enum, default_value_t = Backend::Auto)]
        backend: Backend,
        /// Output size, WIDTHxHEIGHT.
        #[arg(long, value_parser = parse_size, default_value = "960x540")]
        size: (u32, u32),
        /// Write the showcase scene file (a commented example of every key) and exit.
        #[arg(long)]
        print_scene: bool,
    },
    /// Render a scene file to a PNG.
    Render {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output PNG.
        #[arg(short, long)]
        output: PathBuf,
        /// Output size, WIDTHxHEIGHT (default: the scene's).
        #[arg(long, value_parser = parse_size)]
        size: Option<(u32, u32)>,
        /// Which renderer to use.
        #[arg(long, value_enum, default_value_t = Backend::Auto)]
        backend: Backend,
        /// Output mode (default: the scene's).
        #[arg(long, value_enum)]
        mode: Option<RenderMode>,
    },
    /// Exact per-pixel NURBS surfaces: render, info, eval, export, check, deviation.
    Nurbs {
        #[command(subcommand)]
        which: nurbs_cmd::NurbsCommand,
    },
    /// Terrain: DEM + geospecific imagery, the active area.
    Terrain {
        #[command(subcommand)]
        which: terrain_cmd::TerrainCommand,
    },
    /// BTF: six-dimensional textures (synth, index, import, export, info, render).
    Btf {
        #[command(subcommand)]
        which: btf_cmd::BtfCommand,
    },
    /// Open a window on a scene, NURBS model, BTF, tile store or ground image.
    #[cfg(feature = "viewer")]
    View(view::ViewArgs),
    /// Open a window (this hitex was built without the viewer).
    #[cfg(not(feature = "viewer"))]
    View {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
        args: Vec<String>,
    },
    /// List GPU adapters, their features and limits.
    Info,
    /// Benchmarks: CPU and GPU renderers on the same frames.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Textured meshes with nearest, bilinear and trilinear filtering.
    Texture(bench::TextureArgs),
    /// The paper's Table 1 models at 512×512, rotating.
    Nurbs(bench::NurbsArgs),
    /// BTF codebook layouts (a)–(f), raw and BC1, a 256×256 quad in 640×480.
    Btf(bench_btf::BtfArgs),
    /// Flight frames over a GST store: trilinear on both backends, span 3×3 / 4×4 / bicubic.
    Terrain(bench_terrain::TerrainArgs),
}

/// The backend a command renders on (`auto`, `cpu`, `gpu`).
pub(crate) use hitex_render::BackendChoice as Backend;

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width '{w}' is not a positive integer"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height '{h}' is not a positive integer"))?;
    let max = hitex_core::scene::desc::MAX_OUTPUT_SIDE;
    if w == 0 || h == 0 || w > max || h > max {
        return Err(format!("{w}x{h} is outside 1..={max}"));
    }
    Ok((w, h))
}

/// A CLI failure: bad input (exit 2) or an internal failure (exit 1).
#[derive(Debug)]
pub enum CliError {
    /// The user's input is wrong.
    Input(String),
    /// Something failed that is not the input's fault.
    Internal(String),
    /// A check ran and found what it was asked to refuse (exit 1).
    Check(String),
    /// What the command needs is missing from this machine (a display, a
    /// GPU): neither the input's fault nor an internal one (exit 1).
    Unavailable(String),
}

impl std::fmt::Display for CliError {
    /// The message alone, as the error line says it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CliError::Input(m) | CliError::Internal(m) | CliError::Check(m) | CliError::Unavailable(m) => {
                f.write_str(m)
            }
        }
    }
}

impl From<hitex_io::IoError> for CliError {
    fn from(e: hitex_io::IoError) -> Self {
        match e {
            // a write that failed (disk full, read-only, I/O error) is not the
            // input's fault; a path that cannot hold the output is
            hitex_io::IoError::Write { .. } => CliError::Internal(e.to_string()),
            _ => CliError::Input(e.to_string()),
        }
    }
}

impl From<RenderError> for CliError {
    fn from(e: RenderError) -> Self {
        match e {
            RenderError::Invalid(m) => CliError::Input(m),
            RenderError::Gpu(g) => CliError::Internal(g.to_string()),
        }
    }
}

/// Opens the backend of a command: `auto` takes a hardware GPU or the CPU
/// backend (`HITEX_SOFTWARE_GPU=1` lets it take a software adapter), and
/// what the library notices (a GPU that failed, the CPU taking over) goes
/// to stderr. `HITEX_GPU_FAULT=device-lost` destroys the GPU device right
/// after it opens, as a driver reset would (for testing the fallback paths).
pub fn open_renderer(choice: BackendChoice) -> Result<AnyRenderer, CliError> {
    let mut r = AnyRenderer::open_with(choice, open_options()).map_err(|e| match e {
        hitex_render::GpuError::NoAdapter => {
            CliError::Input(format!("--backend gpu: {e}; --backend cpu or auto render without one"))
        }
        e => CliError::Internal(e.to_string()),
    })?;
    r.on_notice(|n| eprintln!("hitex: {n}"));
    Ok(r)
}

/// How renderers open: `HITEX_SOFTWARE_GPU` lets `auto` take a software
/// adapter, `HITEX_GPU_FAULT=device-lost` loses the device at once (for
/// testing the fallbacks).
pub fn open_options() -> OpenOptions {
    OpenOptions {
        software_for_auto: std::env::var_os("HITEX_SOFTWARE_GPU").is_some(),
        lose_device: std::env::var("HITEX_GPU_FAULT").is_ok_and(|f| f == "device-lost"),
    }
}

/// Renders `job` and returns its image.
pub fn render_frame(r: &mut impl Renderer, job: &Job<'_>, (w, h): (u32, u32)) -> Result<Frame, RenderError> {
    Ok(r.render(job, w, h)?.frame)
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
}

/// The image formats a rendered frame can be written in, named by the
/// output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageOut {
    /// `.png`: lossless RGBA.
    Png,
    /// `.jpg` / `.jpeg`: RGB at quality 92.
    Jpeg,
}

/// The format an output image path names, or a refusal naming the accepted
/// extensions (checked before any work, so a wrong name costs nothing).
pub fn image_out(path: &Path) -> Result<ImageOut, CliError> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => Ok(ImageOut::Png),
        Some("jpg" | "jpeg") => Ok(ImageOut::Jpeg),
        _ => Err(CliError::Input(format!(
            "{}: an output image must end in .png, .jpg or .jpeg (the extension names the format)",
            path.display()
        ))),
    }
}

/// Writes a frame in the format its extension names (PNG or JPEG), atomically.
pub fn save(frame: &Frame, path: &Path) -> Result<(), CliError> {
    match image_out(path)? {
        ImageOut::Png => hitex_io::save_png(path, frame.width, frame.height, &frame.rgba).map_err(CliError::from),
        ImageOut::Jpeg => {
            let rgb: Vec<u8> = frame.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
            let mut buf = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, 92)
                .encode(&rgb, frame.width, frame.height, image::ExtendedColorType::Rgb8)
                .map_err(|e| CliError::Internal(format!("{}: {e}", path.display())))?;
            hitex_io::write_atomic(path, &buf).map_err(CliError::from)
        }
    }
}

fn run(cli: Cli) -> Result<(), CliError> {
    // the memory cap: --max-memory, else HITEX_MAX_MEMORY, else the library's default
    let from_env = std::env::var("HITEX_MAX_MEMORY").ok().and_then(|v| match hitex_io::limits::parse_bytes(&v) {
        Ok(b) => Some(b),
        Err(e) => {
            eprintln!("hitex: HITEX_MAX_MEMORY ignored: {e}");
            None
        }
    });
    if let Some(cap) = cli.max_memory.or(from_env) {
        hitex_io::limits::set_max_bytes(cap);
    }
    match cli.command {
        Command::Demo { out, backend, size, print_scene } => {
            if print_scene {
                say_part!("{}", hitex_core::scene::SHOWCASE_TOML);
                return Ok(());
            }
            demo::run(&out, backend, size)
        }
        Command::Render { scene, output, size, backend, mode } => {
            image_out(&output)?;
            let mut s = hitex_io::load_scene(&scene)?;
            if let Some(m) = mode {
                s.mode = m;
            }
            let (w, h) = size.unwrap_or((s.width, s.height));
            let prepared = PreparedScene::new(&s);
            let mut r = open_renderer(backend)?;
            let spinner = indicatif::ProgressBar::new_spinner();
            spinner.set_message(format!("rendering {w}x{h} with {}", r.name()));
            spinner.enable_steady_tick(std::time::Duration::from_millis(120));
            let t = Instant::now();
            let frame = render_frame(&mut r, &Job::Scene { scene: &prepared, camera: prepared.camera }, (w, h));
            spinner.finish_and_clear();
            let mut frame = frame?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            if s.mode == hitex_core::scene::RenderMode::Level {
                let levels = s.textures.iter().map(|t| t.level_count()).max().unwrap_or(1);
                hitex_render::legend::level_legend(&mut frame, levels);
            }
            save(&frame, &output)?;
            let patches =
                prepared.nurbs.as_ref().map_or(String::new(), |n| format!(", {} NURBS patches", n.patch_count()));
            say!(
                "wrote {} ({w}x{h}, {} triangles{patches}, {}) in {ms:.1} ms",
                output.display(),
                prepared.triangle_count(),
                r.name()
            );
            Ok(())
        }
        Command::Nurbs { which } => nurbs_cmd::run(which),
        Command::Terrain { which } => terrain_cmd::run(which),
        Command::Btf { which } => btf_cmd::run(which),
        #[cfg(feature = "viewer")]
        Command::View(args) => view::run(args),
        #[cfg(not(feature = "viewer"))]
        Command::View { .. } => Err(CliError::Input(
            "this hitex was built without the viewer: build it with the default features (cargo feature `viewer`)"
                .into(),
        )),
        Command::Info => {
            say!("hitex {}", env!("CARGO_PKG_VERSION"));
            say!("processor: {}", hitex_render::cpu::simd::processor());
            let simd = hitex_render::cpu::simd::level();
            let levels: Vec<&str> =
                hitex_render::cpu::simd::SimdLevel::available_levels().iter().map(|l| l.name()).collect();
            say!(
                "cpu backend: {} threads, SIMD {simd} ({} f32 lanes per instruction; this processor runs {}; HITEX_SIMD forces one)",
                rayon_threads(),
                simd.width(),
                levels.join(", ")
            );
            let gathers = if hitex_render::cpu::simd::vector_gathers(simd) {
                "AVX-512 vector gathers"
            } else if simd == hitex_render::cpu::simd::SimdLevel::Avx512 {
                "lane by lane (the kernel reports the Gather Data Sampling microcode mitigation, which slows vector gathers)"
            } else {
                "lane by lane"
            };
            say!("  texture reads: {gathers}");
            let textured = hitex_render::cpu::simd::level_for_gathers();
            if textured != simd {
                say!(
                    "  the textured program runs at {textured}: this processor splits 512-bit operations in two, and its gathers measured faster at 8 lanes than at 16 (HITEX_SIMD={simd} runs it at {simd})"
                );
            }
            say_part!("{}", hitex_render::adapters_report());
            Ok(())
        }
        Command::Bench { which } => match which {
            BenchCommand::Texture(args) => bench::texture(args),
            BenchCommand::Nurbs(args) => bench::nurbs(args),
            BenchCommand::Btf(args) => bench_btf::btf(args),
            BenchCommand::Terrain(args) => bench_terrain::terrain(args),
        },
    }
}

/// Lets every command and subcommand take values that look like negative numbers.
fn negatives_are_values(c: clap::Command) -> clap::Command {
    c.allow_negative_numbers(true).mut_subcommands(negatives_are_values)
}

/// Extensions that name a file, never a folder.
const FILE_EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "tif", "tiff", "exr", "bmp", "zip", "hbtf", "json", "igs", "iges", "obj", "stp", "step",
    "toml", "txt", "csv", "npy", "npz",
];

/// Refuses a folder output (`-o`) named like a file (`x.png`, `set.zip`),
/// which would otherwise become a folder of that name.
pub(crate) fn folder_output(path: &Path, what: &str) -> Result<(), CliError> {
    if let Some(e) = path.extension().and_then(|e| e.to_str())
        && FILE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str())
        && !path.is_dir()
    {
        return Err(CliError::Input(format!(
            "-o {}: {what} writes a folder; give a folder name, not a .{e} file",
            path.display()
        )));
    }
    Ok(())
}

/// Refuses a file output (`-o`) whose extension is not one of `exts`
/// (lower case), before any work is done.
pub(crate) fn file_output(path: &Path, exts: &[&str], what: &str) -> Result<(), CliError> {
    let ok = path.extension().and_then(|e| e.to_str()).is_some_and(|e| exts.contains(&e.to_ascii_lowercase().as_str()));
    if ok {
        return Ok(());
    }
    let list: Vec<String> = exts.iter().map(|e| format!(".{e}")).collect();
    Err(CliError::Input(format!("-o {}: {what} is written as {}", path.display(), list.join(" or "))))
}

/// `1 patch`, `2 patches`: a count with its noun.
pub(crate) fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The first failed write to stdout other than a closed pipe.
static STDOUT_ERROR: std::sync::Mutex<Option<std::io::Error>> = std::sync::Mutex::new(None);

/// Writes to stdout for [`say!`]: a failure is kept for [`stdout_status`].
pub(crate) fn write_stdout(args: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    if let Err(e) = std::io::stdout().lock().write_fmt(args) {
        note_stdout_error(e);
    }
}

fn note_stdout_error(e: std::io::Error) {
    // a reader that went away (`| head`) is not a failure of the run
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        return;
    }
    let mut slot = STDOUT_ERROR.lock().unwrap_or_else(|p| p.into_inner());
    slot.get_or_insert(e);
}

/// Flushes stdout and returns the first write that failed, if any.
fn stdout_status() -> Result<(), std::io::Error> {
    use std::io::Write as _;
    if let Err(e) = std::io::stdout().lock().flush() {
        note_stdout_error(e);
    }
    match STDOUT_ERROR.lock().unwrap_or_else(|p| p.into_inner()).take() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Lets a command that writes files run to its end when stdout is closed
/// early: SIGPIPE is ignored (its lines go through [`say!`], which drops
/// what cannot be written).
pub(crate) fn keep_going_on_closed_stdout() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN is async-signal-safe
    // and SIG_IGN is a valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}

/// A message as the user reads it: the operating system's error numbers
/// (" (os error 2)"), which the standard library appends to its text and
/// which say nothing the text does not, are left out.
fn plain(m: &str) -> String {
    let mut out = String::with_capacity(m.len());
    let mut rest = m;
    while let Some(i) = rest.find(" (os error ") {
        let tail = &rest[i + " (os error ".len()..];
        let digits = tail.bytes().take_while(u8::is_ascii_digit).count();
        if digits > 0 && tail[digits..].starts_with(')') {
            out.push_str(&rest[..i]);
            rest = &tail[digits + 1..];
        } else {
            out.push_str(&rest[..i + 1]);
            rest = &rest[i + 1..];
        }
    }
    out.push_str(rest);
    out
}

/// Frames are allocated and dropped once per frame (colour and depth, about
/// 2.5 MB at 640×480): glibc's allocator would hand such blocks back to the
/// kernel on every free (a fresh mapping, or trimming the heap's top), and
/// the next frame then pays a page fault per 4 KiB touched, about 1.5 ms a
/// frame at 640×480 on this class of machine. Blocks up to 64 MiB are
/// served from the heap and a free heap top is kept up to 256 MiB, so that
/// a frame reuses the last one's pages.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; called before any
    // thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

fn main() -> ExitCode {
    // `hitex … | head`: end quietly when the reader goes away, as every Unix
    // tool does, instead of panicking inside println!
    #[cfg(unix)]
    // SAFETY: the first statement of main, before any thread starts; SIG_DFL
    // is a valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // Mesa's device-selection Vulkan layer connects to Wayland while the
    // adapters are listed, and libwayland prints "error: XDG_RUNTIME_DIR is
    // invalid" where no session exists, though nothing failed; hitex ranks
    // adapters itself, so the layer is left out there.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() && std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: still before any thread starts.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
    keep_freed_memory();
    // a value such as `-1` is a value of whichever flag takes it (and is
    // refused by that flag's parser, by name), never an unknown option
    let cli = negatives_are_values(<Cli as clap::CommandFactory>::command())
        .try_get_matches()
        .and_then(|m| <Cli as clap::FromArgMatches>::from_arg_matches(&m))
        .unwrap_or_else(|e| e.exit());
    if let Err(m) = hitex_render::cpu::simd::level_from_env() {
        eprintln!("hitex: error: {m}");
        return ExitCode::from(2);
    }
    let result = run(cli);
    // what the run printed must have reached stdout: a report lost to a
    // full disk is a failed run, never a pass
    if let Err(e) = stdout_status() {
        eprintln!("hitex: error: cannot write to standard output: {}", plain(&e.to_string()));
        if result.is_ok() {
            return ExitCode::from(1);
        }
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::Input(m)) => {
            eprintln!("hitex: error: {}", plain(&m));
            ExitCode::from(2)
        }
        Err(CliError::Internal(m)) => {
            eprintln!("hitex: internal error: {}", plain(&m));
            ExitCode::from(1)
        }
        Err(CliError::Check(m)) => {
            eprintln!("hitex: check failed: {}", plain(&m));
            ExitCode::from(1)
        }
        Err(CliError::Unavailable(m)) => {
            eprintln!("hitex: error: {}", plain(&m));
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::plain;

    #[test]
    fn os_error_numbers_are_left_out() {
        assert_eq!(plain("a.igs: No such file or directory (os error 2)"), "a.igs: No such file or directory");
        assert_eq!(
            plain("cannot write o/x.png: No space left on device (os error 28); o/y.png: Read-only (os error 30)"),
            "cannot write o/x.png: No space left on device; o/y.png: Read-only"
        );
        // text that only looks alike stays
        assert_eq!(plain("a (os error x) b (os error 12"), "a (os error x) b (os error 12");
        assert_eq!(plain("no error here"), "no error here");
    }

    /// The command line takes the libraries' enums, and clap's names for
    /// them are the libraries' names (scene files, viewer, reports, JSON).
    #[test]
    fn command_line_names_are_the_libraries_names() {
        use clap::ValueEnum;
        use hitex_core::scene::RenderMode;
        use hitex_render::nurbs::NurbsMode;
        use hitex_render::terrain::FlySampler;
        fn clap_name<T: ValueEnum>(v: &T) -> String {
            v.to_possible_value().map(|p| p.get_name().to_string()).unwrap_or_default()
        }
        assert_eq!(NurbsMode::value_variants().len(), NurbsMode::ALL.len());
        for (name, m) in NurbsMode::ALL {
            assert_eq!(clap_name(&m), name);
            assert_eq!(m.name(), name);
        }
        assert_eq!(RenderMode::value_variants().len(), RenderMode::ALL.len());
        for (name, m) in RenderMode::ALL {
            assert_eq!(clap_name(&m), name);
            assert_eq!(m.name(), name);
        }
        assert_eq!(FlySampler::value_variants(), FlySampler::ALL);
        for s in FlySampler::ALL {
            assert_eq!(clap_name(&s), s.name());
            assert_eq!(FlySampler::from_name(s.name()), Some(s));
        }
        let backends: Vec<String> = super::Backend::value_variants().iter().map(clap_name).collect();
        assert_eq!(backends, ["auto", "cpu", "gpu"]);
    }
}
