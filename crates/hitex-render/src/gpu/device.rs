//! Adapter choice, device creation and the adapter report of `hitex info`.

use super::GpuError;
use std::fmt::Write;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A wgpu instance over every backend, honouring `WGPU_BACKEND` and the
/// other wgpu environment variables.
pub fn instance() -> wgpu::Instance {
    instance_for(wgpu::Backends::all())
}

/// A wgpu instance over `backends` (`WGPU_BACKEND` overrides them). Leaving
/// GL out avoids initialising EGL, whose probe prints "error:" lines on a
/// machine without a display even when nothing fails.
pub fn instance_for(backends: wgpu::Backends) -> wgpu::Instance {
    let mut d = wgpu::InstanceDescriptor::new_without_display_handle();
    d.backends = backends;
    wgpu::Instance::new(d.with_env())
}

/// Whether an adapter is a hardware GPU (not a software rasterizer such as
/// lavapipe/llvmpipe or SwiftShader).
pub fn is_hardware(info: &wgpu::AdapterInfo) -> bool {
    info.device_type != wgpu::DeviceType::Cpu
}

/// The device hitex asks of `adapter`: the adapter's own limits and the
/// features hitex can use that it has (BC texture compression, filterable
/// float textures). An application that opens the device itself and hands
/// it to [`GpuContext::on_device`] (e.g. as eframe's
/// `WgpuSetupCreateNew::device_descriptor`) gets every layout hitex draws.
pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
    let wanted = wgpu::Features::TEXTURE_COMPRESSION_BC
        | wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D
        | wgpu::Features::FLOAT32_FILTERABLE;
    wgpu::DeviceDescriptor {
        label: Some("hitex"),
        required_features: adapter.features() & wanted,
        required_limits: adapter.limits(),
        ..Default::default()
    }
}

/// Ranks adapters: real GPUs first, then software Vulkan (lavapipe), then GL.
fn rank(info: &wgpu::AdapterInfo) -> u32 {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    let backend = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    kind * 2 + backend
}

/// Every adapter the instance finds, best first.
pub fn adapters(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let mut list = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    list.sort_by_key(|a| rank(&a.get_info()));
    list
}

/// The adapters of the primary backends (Vulkan, Metal, DX12), best first;
/// GL only when those find none (or `WGPU_BACKEND` asks for it).
fn adapters_primary_first() -> Vec<wgpu::Adapter> {
    let list = adapters(&instance_for(wgpu::Backends::PRIMARY));
    if !list.is_empty() || wgpu::Backends::from_env().is_some() {
        return list;
    }
    adapters(&instance_for(wgpu::Backends::GL))
}

/// An open device with its adapter.
pub struct GpuContext {
    /// The chosen adapter.
    pub adapter: wgpu::Adapter,
    /// Its device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Adapter description.
    pub info: wgpu::AdapterInfo,
    /// Set by the device-lost callback: why the device was lost.
    lost: Arc<Mutex<Option<String>>>,
    /// Errors the device reported outside an error scope (at most 16 kept).
    uncaptured: Arc<Mutex<Vec<String>>>,
}

/// How long one GPU wait may take before it counts as a hang, in seconds
/// (`HITEX_GPU_TIMEOUT`, default 300: the slowest frame hitex renders on a
/// software rasterizer takes a few seconds).
pub fn gpu_timeout() -> Duration {
    let secs = std::env::var("HITEX_GPU_TIMEOUT").ok().and_then(|v| v.trim().parse::<f64>().ok());
    Duration::from_secs_f64(secs.filter(|s| s.is_finite() && *s > 0.0).unwrap_or(300.0).min(86_400.0))
}

impl GpuContext {
    /// Opens the best adapter, requesting its own limits and the features
    /// hitex can use (BC texture compression, filterable float textures).
    pub fn new() -> Result<Self, GpuError> {
        let adapter = adapters_primary_first().into_iter().next().ok_or(GpuError::NoAdapter)?;
        Self::open(adapter)
    }

    /// Opens the best adapter if it is a hardware GPU; a software rasterizer
    /// alone is [`GpuError::SoftwareOnly`] (what `--backend auto` checks).
    pub fn hardware() -> Result<Self, GpuError> {
        let adapter = adapters_primary_first().into_iter().next().ok_or(GpuError::NoAdapter)?;
        let info = adapter.get_info();
        if !is_hardware(&info) {
            return Err(GpuError::SoftwareOnly(describe(&info)));
        }
        Self::open(adapter)
    }

    /// Like [`GpuContext::new`], choosing only among adapters of `backends`.
    pub fn with_backends(backends: wgpu::Backends) -> Result<Self, GpuError> {
        let instance = instance_for(backends);
        let adapter = adapters(&instance)
            .into_iter()
            .find(|a| backends.contains(wgpu::Backends::from(a.get_info().backend)))
            .ok_or(GpuError::NoAdapter)?;
        Self::open(adapter)
    }

    /// Wraps a device that an application opened itself, so that hitex
    /// renders beside the application's own work. hitex installs no error or
    /// device-lost callback on a device it does not own: a loss shows as the
    /// next render's error instead. Compressed BTF layouts need
    /// `TEXTURE_COMPRESSION_BC` among the device's features.
    pub fn on_device(adapter: wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let info = adapter.get_info();
        Self { adapter, device, queue, info, lost: Arc::default(), uncaptured: Arc::default() }
    }

    /// Opens a device on `adapter`.
    fn open(adapter: wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let desc = device_descriptor(&adapter);
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| GpuError::Device(format!("{} ({:?}): {e}", info.name, info.backend)))?;
        // errors outside an error scope are reported, never a panic
        let lost: Arc<Mutex<Option<String>>> = Arc::default();
        // errors outside an error scope are reported, never a panic; after a loss they are only its echo
        let quiet = lost.clone();
        let uncaptured: Arc<Mutex<Vec<String>>> = Arc::default();
        let keep = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if quiet.lock().map(|l| l.is_none()).unwrap_or(true)
                && let Ok(mut u) = keep.lock()
                && u.len() < 16
            {
                u.push(e.to_string());
            }
        }));
        let record = lost.clone();
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut l) = record.lock() {
                let why = match reason {
                    wgpu::DeviceLostReason::Destroyed => "destroyed".to_string(),
                    other => format!("{other:?}").to_lowercase(),
                };
                l.get_or_insert_with(|| match message.trim() {
                    "" => why,
                    m => format!("{why}: {m}"),
                });
            }
        });
        Ok(Self { adapter, device, queue, info, lost, uncaptured })
    }

    /// The errors the device reported outside an error scope since the last
    /// call (hitex prints nothing itself; [`crate::AnyRenderer`] passes them
    /// on as notices).
    pub fn take_uncaptured(&self) -> Vec<String> {
        self.uncaptured.lock().map(|mut u| std::mem::take(&mut *u)).unwrap_or_default()
    }

    /// `Err` once the device is lost (driver reset, removal, or [`GpuContext::lose_device`]).
    pub fn alive(&self) -> Result<(), GpuError> {
        match self.lost.lock().ok().and_then(|l| l.clone()) {
            Some(why) => Err(GpuError::Lost(why)),
            None => Ok(()),
        }
    }

    /// Destroys the device, as a driver reset would: every later render
    /// returns [`GpuError::Lost`]. For testing the fallback paths.
    pub fn lose_device(&self) {
        self.device.destroy();
        // the callback runs on the next poll; make the loss visible at once
        let _ = self.device.poll(wgpu::PollType::Poll);
        if let Ok(mut l) = self.lost.lock() {
            l.get_or_insert_with(|| "destroyed".into());
        }
    }

    /// Waits for the submitted work, at most [`gpu_timeout`]; a device lost
    /// meanwhile or a hang becomes an error, never a wait without end.
    pub fn wait(&self) -> Result<(), GpuError> {
        let timeout = gpu_timeout();
        let r = self.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(timeout) });
        self.alive()?;
        match r {
            Ok(_) => Ok(()),
            Err(wgpu::PollError::Timeout) => Err(GpuError::Timeout(timeout.as_secs_f64())),
            Err(e) => Err(GpuError::Readback(e.to_string())),
        }
    }

    /// "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)".
    pub fn describe(&self) -> String {
        describe(&self.info)
    }
}

/// One-line adapter description.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

/// Multi-line report of every adapter: name, backend, type, driver, the
/// features hitex cares about and the main limits.
pub fn adapters_report() -> String {
    let instance = instance();
    let list = adapters(&instance);
    let mut s = String::new();
    if list.is_empty() {
        s.push_str("no GPU adapter found (install mesa-vulkan-drivers for lavapipe); the CPU backend is used\n");
        return s;
    }
    for (i, a) in list.iter().enumerate() {
        let info = a.get_info();
        let f = a.features();
        let l = a.limits();
        let _ = writeln!(s, "adapter {i}{}: {}", if i == 0 { " (--backend gpu)" } else { "" }, describe(&info));
        let _ = writeln!(s, "  driver: {} {}", info.driver, info.driver_info);
        let _ = writeln!(
            s,
            "  features: TEXTURE_COMPRESSION_BC {} (3-D {}), FLOAT32_FILTERABLE {}",
            f.contains(wgpu::Features::TEXTURE_COMPRESSION_BC),
            f.contains(wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D),
            f.contains(wgpu::Features::FLOAT32_FILTERABLE)
        );
        let _ = writeln!(
            s,
            "  limits: 2-D {}, 3-D {}, array layers {}, storage binding {} MiB, buffer {} MiB",
            l.max_texture_dimension_2d,
            l.max_texture_dimension_3d,
            l.max_texture_array_layers,
            l.max_storage_buffer_binding_size >> 20,
            l.max_buffer_size >> 20
        );
    }
    let _ = match list.first().map(|a| a.get_info()) {
        Some(info) if is_hardware(&info) => writeln!(s, "--backend auto: the GPU {}", describe(&info)),
        _ => writeln!(s, "--backend auto: the CPU backend (no hardware GPU; a software rasterizer is slower than it)"),
    };
    s
}
