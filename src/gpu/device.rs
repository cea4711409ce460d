//! Adapter and device selection.
//!
//! The instance honours wgpu's environment variables: `WGPU_BACKEND` (e.g. `vulkan`, `metal`,
//! `dx12`), `WGPU_POWER_PREF` (`low` / `high`) and `WGPU_ADAPTER_NAME` (a case-insensitive
//! substring of the adapter's name; an error, not a fallback, when nothing matches).

use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};

/// What the chosen adapter is and offers.
#[derive(Debug, Clone, PartialEq)]
pub struct GpuInfo {
    /// Adapter name, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
    pub name: String,
    /// Graphics API: "vulkan", "metal", "dx12", ...
    pub backend: String,
    /// "DiscreteGpu", "IntegratedGpu", "VirtualGpu", "Cpu" or "Other".
    pub device_type: String,
    /// Driver name and version information.
    pub driver: String,
    /// Whether the adapter offers 64-bit floats in shaders (SHADER_F64). The backend itself
    /// runs in f32 on every adapter.
    pub f64: bool,
    /// The limits that matter here, by their wgpu names.
    pub limits: Vec<(&'static str, u64)>,
}

/// An open device on the chosen adapter, with the errors it reported since the last check
/// (clones share the device).
#[derive(Clone)]
pub(super) struct GpuContext {
    pub(super) device: wgpu::Device,
    pub(super) queue: wgpu::Queue,
    pub(super) info: GpuInfo,
    pub(super) limits: wgpu::Limits,
    errors: Arc<Mutex<Vec<String>>>,
}

/// Storage buffers one kernel binds (see shaders/common.wgsl).
pub(super) const STORAGE_BUFFERS: u32 = 18;

/// Picks an adapter (see the module documentation).
fn adapter() -> Result<wgpu::Adapter> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let hint = "install a Vulkan, Metal or DX12 driver (on Linux without a GPU: Mesa's lavapipe, \
                `apt-get install mesa-vulkan-drivers libvulkan1`), or use backend=\"cpu\"";
    if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME") {
        let wanted = wanted.to_lowercase();
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        return adapters
            .into_iter()
            .find(|a| a.get_info().name.to_lowercase().contains(&wanted))
            .ok_or_else(|| {
                Error::Gpu(format!(
                    "no GPU adapter matches WGPU_ADAPTER_NAME={wanted:?} (available: {names:?}); {hint}"
                ))
            });
    }
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::from_env().unwrap_or_default(),
        ..Default::default()
    };
    pollster::block_on(instance.request_adapter(&options)).map_err(|e| {
        Error::Gpu(format!(
            "no GPU adapter found ({e}; WGPU_BACKEND={:?}); {hint}",
            std::env::var("WGPU_BACKEND").unwrap_or_default()
        ))
    })
}

fn describe(adapter: &wgpu::Adapter) -> GpuInfo {
    let info = adapter.get_info();
    let l = adapter.limits();
    GpuInfo {
        name: info.name,
        backend: format!("{:?}", info.backend).to_lowercase(),
        device_type: format!("{:?}", info.device_type),
        driver: format!("{} {}", info.driver, info.driver_info)
            .trim()
            .to_string(),
        f64: adapter.features().contains(wgpu::Features::SHADER_F64),
        limits: vec![
            (
                "max_storage_buffer_binding_size",
                l.max_storage_buffer_binding_size,
            ),
            (
                "max_storage_buffers_per_shader_stage",
                l.max_storage_buffers_per_shader_stage as u64,
            ),
            ("max_buffer_size", l.max_buffer_size),
            (
                "max_compute_workgroups_per_dimension",
                l.max_compute_workgroups_per_dimension as u64,
            ),
            (
                "max_compute_invocations_per_workgroup",
                l.max_compute_invocations_per_workgroup as u64,
            ),
        ],
    }
}

/// Describes the adapter the GPU backend would use, or says what is missing.
pub fn gpu_info() -> Result<GpuInfo> {
    Ok(describe(&adapter()?))
}

impl GpuContext {
    /// Opens a device on the chosen adapter with `features`, asking for the adapter's own
    /// limits (the kernels bind [`STORAGE_BUFFERS`] storage buffers, more than WebGPU's
    /// default of 8).
    pub(super) fn new(features: wgpu::Features) -> Result<Self> {
        let adapter = adapter()?;
        let info = describe(&adapter);
        let missing = features - adapter.features();
        if !missing.is_empty() {
            return Err(Error::Gpu(format!(
                "GPU adapter {:?} lacks {missing:?} (64-bit floats in shaders); use precision='f32'",
                info.name
            )));
        }
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            return Err(Error::Gpu(format!(
                "GPU adapter {:?} binds at most {} storage buffers per shader stage; the GPU backend needs {STORAGE_BUFFERS}",
                info.name, limits.max_storage_buffers_per_shader_stage
            )));
        }
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("peridyn"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&descriptor))
            .map_err(|e| Error::Gpu(format!("cannot open a device on {:?}: {e}", info.name)))?;
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let message = match e {
                wgpu::Error::Validation { description, .. }
                | wgpu::Error::Internal { description, .. } => description,
                other => other.to_string(),
            };
            if let Ok(mut list) = sink.lock() {
                list.push(message);
            }
        }));
        Ok(Self {
            device,
            queue,
            info,
            limits,
            errors,
        })
    }

    /// Fails with the errors the device reported since the last call, if any.
    pub(super) fn check(&self) -> Result<()> {
        let mut list = self.errors.lock().unwrap_or_else(|p| p.into_inner());
        if list.is_empty() {
            return Ok(());
        }
        let all = std::mem::take(&mut *list);
        let more = match all.len() {
            1 => String::new(),
            n => format!(" (and {} more)", n - 1),
        };
        Err(Error::Gpu(format!("GPU device error: {}{more}", all[0])))
    }

    /// Blocks until the queue is idle.
    pub(super) fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("GPU device lost while waiting: {e}")))?;
        Ok(())
    }
}
