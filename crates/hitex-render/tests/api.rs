//! The one render API: jobs on every backend, the CPU taking over under
//! `auto`, notices instead of printing, a caller's own wgpu device.

mod common;

use common::*;
use hitex_render::nurbs::PreparedNurbs;
use hitex_render::terrain::{FlyCamera, FlyGround, FlyPages, FlyUniform};
use hitex_render::{
    AnyRenderer, BackendChoice, CpuRenderer, Engine, GpuError, GpuRenderer, Job, OpenOptions, RenderError, Renderer,
};
use std::borrow::Cow;
use std::sync::{Arc, Mutex};

const S: u32 = 96;

fn teapot() -> PreparedNurbs {
    let m = hitex_io::models::load_model("teapot").unwrap();
    PreparedNurbs::new(m.nurbs(), &m.ranges(), 4)
}

/// True when a GPU adapter exists; a visible skip (or a failure under
/// `HITEX_REQUIRE_GPU=1`) when none does.
fn have_gpu(test: &str) -> bool {
    gpu_or_skip(test).is_some()
}

#[test]
fn a_flight_job_for_another_size_is_refused_on_every_backend() {
    let cam = FlyCamera::new(0.5, 0.5, 2000.0, 30.0, 0.0, 45.0);
    let uniform = FlyUniform::new(&cam, 64, 48, 1, 1);
    let pages = FlyPages { levels: 1, per_side: 1, origins: vec![[0, 0]], slots: vec![None], maps: Default::default() };
    let job = Job::Flight { uniform, pages: Cow::Owned(pages), ground: FlyGround::Flat, stats: false };
    let mut cpu = CpuRenderer::new();
    match cpu.render(&job, 64, 64) {
        Err(RenderError::Invalid(m)) => assert!(m.contains("64x48") && m.contains("64x64"), "{m}"),
        other => panic!("expected a refusal, got {:?}", other.map(|r| r.frame.width)),
    }
    if let Some(mut gpu) = gpu_or_skip("a_flight_job_for_another_size_is_refused_on_every_backend") {
        assert!(matches!(gpu.render(&job, 64, 64), Err(RenderError::Invalid(_))));
    }
}

#[test]
fn the_cpu_choice_renders_what_the_cpu_backend_renders() {
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    let mut any = AnyRenderer::open(BackendChoice::Cpu).unwrap();
    assert!(!any.is_gpu());
    assert!(any.name().starts_with("cpu ("), "{}", any.name());
    let a = any.render(&job, S, S).unwrap().frame;
    let b = CpuRenderer::new().render_nurbs(&p, &p.camera, S, S).unwrap();
    assert_eq!(a, b);
    assert!(any.take_notices().is_empty());
}

#[test]
fn auto_continues_on_the_cpu_when_the_device_is_lost_and_says_so_once() {
    if !have_gpu("auto_continues_on_the_cpu_when_the_device_is_lost_and_says_so_once") {
        return;
    }
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    let options = OpenOptions { software_for_auto: true, lose_device: true };
    let mut any = AnyRenderer::open_with(BackendChoice::Auto, options).unwrap();
    assert!(any.is_gpu(), "auto with software_for_auto takes the software adapter");
    let said = Arc::new(Mutex::new(Vec::<String>::new()));
    let sink = said.clone();
    any.on_notice(move |n| sink.lock().unwrap().push(n.to_string()));
    let first = any.render(&job, S, S).unwrap().frame;
    assert!(matches!(any.engine(), Engine::Cpu(_)), "the CPU took over");
    let second = any.render(&job, S, S).unwrap().frame;
    let cpu = CpuRenderer::new().render_nurbs(&p, &p.camera, S, S).unwrap();
    assert_eq!(first, cpu, "the frame of the failed render is the CPU's");
    assert_eq!(second, cpu);
    let said = said.lock().unwrap().clone();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(said[0].contains("lost") && said[0].contains("CPU"), "{said:?}");
    assert!(any.take_notices().is_empty(), "notices went to the sink");
}

#[test]
fn the_gpu_choice_reports_a_lost_device_instead_of_falling_back() {
    if !have_gpu("the_gpu_choice_reports_a_lost_device_instead_of_falling_back") {
        return;
    }
    let p = teapot();
    let options = OpenOptions { software_for_auto: false, lose_device: true };
    let mut any = AnyRenderer::open_with(BackendChoice::Gpu, options).unwrap();
    match any.render(&Job::Nurbs { model: &p, camera: p.camera }, S, S) {
        Err(RenderError::Gpu(GpuError::Lost(_))) => {}
        other => panic!("expected a lost device, got {:?}", other.map(|r| r.frame.width)),
    }
    assert!(any.is_gpu());
    assert!(any.take_notices().is_empty());
}

/// The first adapter and a device opened on it, as an application opens
/// them, with the adapter's limits as `limits` changes them.
fn own_device(limits: impl FnOnce(wgpu::Limits) -> wgpu::Limits) -> (wgpu::Adapter, wgpu::Device, wgpu::Queue) {
    let instance = hitex_render::gpu::device::instance();
    let adapter = hitex_render::gpu::device::adapters(&instance).into_iter().next().expect("an adapter");
    let desc = wgpu::DeviceDescriptor { required_limits: limits(adapter.limits()), ..Default::default() };
    let (device, queue) = pollster::block_on(adapter.request_device(&desc)).unwrap();
    (adapter, device, queue)
}

#[test]
fn a_renderer_on_the_callers_own_device_matches_the_cpu() {
    if !have_gpu("a_renderer_on_the_callers_own_device_matches_the_cpu") {
        return;
    }
    // the application opens its adapter and device itself
    let (adapter, device, queue) = own_device(|_| wgpu::Limits::default());
    let mut gpu = GpuRenderer::on_device(adapter, device.clone(), queue).unwrap();
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    let g = gpu.render(&job, S, S).unwrap().frame;
    let c = CpuRenderer::new().render(&job, S, S).unwrap().frame;
    assert_images("api_on_device_nurbs", &g, &c, GPU_VS_CPU);
    // the application's device stays usable beside hitex
    let buf = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 256,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    drop(buf);
}

#[test]
fn data_textures_beyond_the_devices_limit_are_refused_by_name() {
    if !have_gpu("data_textures_beyond_the_devices_limit_are_refused_by_name") {
        return;
    }
    // a device opened with a 16-texel limit per side: the 16² target fits,
    // the teapot's data textures (a row per patch, 32 patches) do not
    let (adapter, device, queue) = own_device(|l| wgpu::Limits { max_texture_dimension_2d: 16, ..l });
    let mut gpu = GpuRenderer::on_device(adapter, device, queue).unwrap();
    let p = teapot();
    match gpu.render(&Job::Nurbs { model: &p, camera: p.camera }, 16, 16) {
        Err(RenderError::Gpu(GpuError::Render(m))) => {
            assert!(m.contains("texture needs") && m.contains("the device allows 16 per side"), "{m}")
        }
        Err(e) => panic!("expected the texture's refusal, got {e}"),
        Ok(_) => panic!("textures beyond the device's 16 texels a side were accepted"),
    }
}

#[test]
fn one_loop_renders_every_pillar_on_both_backends() {
    let Some(gpu) = gpu_or_skip("one_loop_renders_every_pillar_on_both_backends") else {
        return;
    };
    let p = teapot();
    let scene = hitex_render::PreparedScene::new(&hitex_core::scene::showcase_scene());
    let jobs = [Job::Nurbs { model: &p, camera: p.camera }, Job::Scene { scene: &scene, camera: scene.camera }];
    let mut backends: Vec<Box<dyn Renderer>> = vec![Box::new(CpuRenderer::new()), Box::new(gpu)];
    for job in &jobs {
        let frames: Vec<_> = backends.iter_mut().map(|r| r.render(job, S, S).unwrap().frame).collect();
        assert_images(&format!("api_loop_{}", job.kind()), &frames[1], &frames[0], GPU_VS_CPU);
    }
}

/// A texture the application owns, as a viewer makes one to show.
fn app_texture(device: &wgpu::Device, format: wgpu::TextureFormat, usage: wgpu::TextureUsages) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("the application's"),
        size: wgpu::Extent3d { width: S, height: S, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// The texture's pixels, read back as the application would.
fn read_texture(device: &wgpu::Device, queue: &wgpu::Queue, t: &wgpu::Texture) -> Vec<u8> {
    let row = (4 * S).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buf = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * S) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        t.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(S) },
        },
        t.size(),
    );
    queue.submit([enc.finish()]);
    buf.slice(..).map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).unwrap();
    let data = buf.slice(..).get_mapped_range().unwrap();
    data.chunks(row as usize).flat_map(|r| r[..4 * S as usize].to_vec()).collect()
}

#[test]
fn rendering_into_the_callers_texture_draws_what_render_reads_back() {
    if !have_gpu("rendering_into_the_callers_texture_draws_what_render_reads_back") {
        return;
    }
    let (adapter, device, queue) = own_device(|_| wgpu::Limits::default());
    let mut gpu = GpuRenderer::on_device(adapter, device.clone(), queue.clone()).unwrap();
    let p = teapot();
    let scene = hitex_render::PreparedScene::new(&hitex_core::scene::showcase_scene());
    let jobs = [Job::Nurbs { model: &p, camera: p.camera }, Job::Scene { scene: &scene, camera: scene.camera }];
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
    let target = app_texture(&device, wgpu::TextureFormat::Rgba8Unorm, usage);
    for job in &jobs {
        gpu.render_into(job, &target).unwrap();
        let drawn = read_texture(&device, &queue, &target);
        // the read-back render after it still reads its own target back
        let read = gpu.render(job, S, S).unwrap().frame;
        assert_eq!((read.width, read.height), (S, S));
        assert!(drawn == read.rgba, "{}: the texture differs from the frame read back", job.kind());
        assert!(drawn.chunks(4).any(|p| p != &drawn[..4]), "{}: an empty image", job.kind());
    }
}

#[test]
fn targets_the_renderer_cannot_draw_into_are_refused_by_what_they_lack() {
    if !have_gpu("targets_the_renderer_cannot_draw_into_are_refused_by_what_they_lack") {
        return;
    }
    let (adapter, device, queue) = own_device(|_| wgpu::Limits::default());
    let mut gpu = GpuRenderer::on_device(adapter, device.clone(), queue).unwrap();
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
    for (t, says) in [
        (app_texture(&device, wgpu::TextureFormat::Rgba8UnormSrgb, attach), "must be Rgba8Unorm"),
        (app_texture(&device, wgpu::TextureFormat::Bgra8Unorm, attach), "not Bgra8Unorm"),
        (
            app_texture(&device, wgpu::TextureFormat::Rgba8Unorm, wgpu::TextureUsages::TEXTURE_BINDING),
            "RENDER_ATTACHMENT",
        ),
    ] {
        match gpu.render_into(&job, &t) {
            Err(RenderError::Invalid(m)) => assert!(m.contains(says), "{m}"),
            other => panic!("expected a refusal naming {says}, got {:?}", other.err()),
        }
    }
    // the renderer still draws after the refusals
    let ok = app_texture(&device, wgpu::TextureFormat::Rgba8Unorm, attach);
    gpu.render_into(&job, &ok).unwrap();
}

#[test]
fn an_any_renderer_on_the_callers_device_draws_into_its_texture_or_hands_back_the_cpu_image() {
    if !have_gpu("an_any_renderer_on_the_callers_device_draws_into_its_texture_or_hands_back_the_cpu_image") {
        return;
    }
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    let cpu = CpuRenderer::new().render(&job, S, S).unwrap().frame;
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
    let open = |choice, options| {
        let (adapter, device, queue) = own_device(|_| wgpu::Limits::default());
        let hardware = hitex_render::gpu::device::is_hardware(&adapter.get_info());
        let target = app_texture(&device, wgpu::TextureFormat::Rgba8Unorm, usage);
        let any = AnyRenderer::on_device(choice, options, adapter, device.clone(), queue.clone()).unwrap();
        (any, target, device, queue, hardware)
    };
    // gpu: drawn into the texture, nothing handed back
    let (mut any, target, device, queue, hardware) = open(BackendChoice::Gpu, OpenOptions::default());
    assert!(any.is_gpu());
    assert!(any.render_into(&job, &target).unwrap().is_none());
    let drawn = read_texture(&device, &queue, &target);
    let read = any.render(&job, S, S).unwrap().frame;
    assert!(drawn == read.rgba, "the texture differs from the frame read back");
    assert_images("api_any_into_nurbs", &read, &cpu, GPU_VS_CPU);
    // cpu: the CPU image handed back
    let (mut any, target, ..) = open(BackendChoice::Cpu, OpenOptions::default());
    assert!(!any.is_gpu());
    assert_eq!(any.render_into(&job, &target).unwrap().map(|r| r.frame), Some(cpu.clone()));
    // auto: a software device is passed over for the CPU, and the name says why
    let (any, ..) = open(BackendChoice::Auto, OpenOptions::default());
    assert_eq!(any.is_gpu(), hardware, "{}", any.name());
    if !hardware {
        assert!(any.name().contains("no hardware GPU"), "{}", any.name());
    }
    // auto on a device that is lost: the CPU takes over, says so once, and hands its image back
    let (mut any, target, ..) = open(BackendChoice::Auto, OpenOptions { software_for_auto: true, lose_device: true });
    assert!(any.is_gpu());
    assert_eq!(any.render_into(&job, &target).unwrap().map(|r| r.frame), Some(cpu.clone()));
    assert!(matches!(any.engine(), Engine::Cpu(_)));
    assert_eq!(any.render_into(&job, &target).unwrap().map(|r| r.frame), Some(cpu));
    let notices = any.take_notices();
    assert_eq!(notices.len(), 1, "{notices:?}");
    assert!(notices[0].contains("CPU"), "{notices:?}");
}

#[test]
fn a_device_the_renderer_cannot_be_built_on_leaves_auto_on_the_cpu() {
    if !have_gpu("a_device_the_renderer_cannot_be_built_on_leaves_auto_on_the_cpu") {
        return;
    }
    // one bind group a pipeline: the renderer's pipelines (two and more) cannot be built
    let one_group = |l: wgpu::Limits| wgpu::Limits { max_bind_groups: 1, ..l };
    let options = OpenOptions { software_for_auto: true, lose_device: false };
    let (adapter, device, queue) = own_device(one_group);
    match AnyRenderer::on_device(BackendChoice::Gpu, options, adapter, device, queue) {
        Err(_) => {}
        Ok(r) => panic!("gpu on a device it cannot use: {}", r.name()),
    }
    let (adapter, device, queue) = own_device(one_group);
    let mut any = AnyRenderer::on_device(BackendChoice::Auto, options, adapter, device, queue).unwrap();
    assert!(!any.is_gpu());
    let notices = any.take_notices();
    assert!(notices.len() == 1 && notices[0].contains("falling back to the CPU"), "{notices:?}");
    let p = teapot();
    let job = Job::Nurbs { model: &p, camera: p.camera };
    assert_eq!(any.render(&job, S, S).unwrap().frame, CpuRenderer::new().render(&job, S, S).unwrap().frame);
}
