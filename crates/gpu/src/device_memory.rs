//! GPU buffers whose memory is made outside wgpu's allocator. wgpu-hal makes every buffer's
//! memory under one lock, and slowly: 14.9 GiB of point buffers took 0.31–0.41 s through it
//! on the H100 and 21–47 ms made by Vulkan directly (docs/BENCHMARKS.md, issue 11, session 46).
//! On Vulkan the memory is made here ([`DirectAllocator`]) and handed to wgpu whole.

use crate::GpuError;
use ash::vk;

/// Makes dedicated memory for buffers through the Vulkan device itself.
pub(crate) struct DirectAllocator {
    /// Keeps the Vulkan device alive while memory made here is not yet wgpu's.
    device: wgpu::Device,
    raw: ash::Device,
    types: vk::PhysicalDeviceMemoryProperties,
}

impl DirectAllocator {
    /// `None` unless `device` runs on Vulkan.
    pub fn new(device: &wgpu::Device) -> Option<Self> {
        // SAFETY: the raw handles are only used while `device` (kept in `Self`) lives.
        let hal = unsafe { device.as_hal::<wgpu::hal::api::Vulkan>() }?;
        let raw = hal.raw_device().clone();
        let instance = hal.shared_instance().raw_instance();
        // SAFETY: the physical device belongs to this instance.
        let types =
            unsafe { instance.get_physical_device_memory_properties(hal.raw_physical_device()) };
        Some(Self {
            device: device.clone(),
            raw,
            types,
        })
    }

    /// A buffer of `size` bytes in device memory (contents undefined: zero it before reading)
    /// for `usage`, which must not ask for mapping.
    pub fn buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        let made = self.make(size, usage, |bits| device_type(&self.types, bits))?;
        let made = made.ok_or_else(|| {
            GpuError::Device(format!("no device-local memory for a {size}-byte buffer"))
        })?;
        Ok(self.hand_over(made, label, size, usage))
    }

    /// A buffer of `size` bytes for `usage` (no mapping) in host memory that the GPU reads
    /// over the bus, mapped for the CPU: `None` where the device has no such memory apart
    /// from its own (an integrated or a CPU GPU).
    pub fn host_buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<Option<MappedBuffer>, GpuError> {
        self.mapped_buffer(label, size, usage, |bits| host_type(&self.types, bits))
    }

    /// Like [`host_buffer`](Self::host_buffer), in the device's own memory that the host sees
    /// (a discrete GPU's resizable BAR; all memory of an integrated or a CPU GPU): memory to
    /// upload through, written by the CPU and copied by the GPU without crossing the bus.
    pub fn upload_buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<Option<MappedBuffer>, GpuError> {
        self.mapped_buffer(label, size, usage, |bits| upload_type(&self.types, bits))
    }

    /// A buffer in memory of the type `choose` picks, mapped whole.
    fn mapped_buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
        choose: impl FnOnce(u32) -> Option<u32>,
    ) -> Result<Option<MappedBuffer>, GpuError> {
        let made = self.make(size, usage, choose)?;
        let Some(made) = made else {
            return Ok(None);
        };
        // SAFETY: host-visible memory of this device, mapped once, whole; it stays mapped
        // until it is freed with the buffer.
        let ptr = unsafe {
            self.raw
                .map_memory(made.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
        }
        .map_err(|e| GpuError::Device(format!("mapping {size} bytes of memory: {e}")))?;
        let len = usize::try_from(size)
            .map_err(|_| GpuError::InvalidInput(format!("{size} bytes of mapped memory")))?;
        let buffer = self.hand_over(made, label, size, usage);
        Ok(Some(MappedBuffer {
            buffer,
            ptr: ptr.cast(),
            len,
        }))
    }

    /// A buffer of `size` bytes for `usage` bound to dedicated memory of the type `choose`
    /// picks among those it may use (`None` when it picks none).
    fn make(
        &self,
        size: u64,
        usage: wgpu::BufferUsages,
        choose: impl FnOnce(u32) -> Option<u32>,
    ) -> Result<Option<Made<'_>>, GpuError> {
        let failed = |what: &str, e: vk::Result| {
            if matches!(
                e,
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY
            ) {
                GpuError::OutOfMemory(format!("making a buffer of {size} bytes"))
            } else {
                GpuError::Device(format!("{what} ({size} bytes): {e}"))
            }
        };
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(vk_usage(usage))
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: a valid create info on a live device.
        let buffer = unsafe { self.raw.create_buffer(&info, None) }
            .map_err(|e| failed("creating a buffer", e))?;
        let mut made = Made {
            raw: &self.raw,
            buffer,
            memory: vk::DeviceMemory::null(),
        };
        // SAFETY: `buffer` was just made on this device.
        let needs = unsafe { self.raw.get_buffer_memory_requirements(buffer) };
        let Some(type_index) = choose(needs.memory_type_bits) else {
            return Ok(None);
        };
        let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().buffer(buffer);
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(needs.size)
            .memory_type_index(type_index)
            .push_next(&mut dedicated);
        // SAFETY: a valid allocate info for one of this device's memory types.
        made.memory = unsafe { self.raw.allocate_memory(&alloc, None) }
            .map_err(|e| failed("making memory", e))?;
        // SAFETY: the memory was made for this buffer's requirements.
        unsafe { self.raw.bind_buffer_memory(buffer, made.memory, 0) }
            .map_err(|e| failed("binding memory", e))?;
        Ok(Some(made))
    }

    /// The buffer of `made` as wgpu's, which frees its memory when it is destroyed.
    fn hand_over(
        &self,
        made: Made<'_>,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let made = std::mem::ManuallyDrop::new(made);
        // SAFETY: the buffer is bound to the whole of its own memory, which wgpu-hal frees
        // when it destroys the buffer.
        let hal = unsafe {
            wgpu::hal::vulkan::Buffer::from_raw_managed(made.buffer, made.memory, 0, size)
        };
        let desc = wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        };
        // SAFETY: made by this device for `desc`'s size and usage; wgpu takes the contents as
        // they are (point memory is zeroed by its maker, mapped memory written before use).
        unsafe {
            self.device
                .create_buffer_from_hal::<wgpu::hal::api::Vulkan>(hal, &desc)
        }
    }
}

/// The device-local memory type among `bits` for a buffer, one the host cannot see where
/// there is such (device memory the host sees is the resizable BAR's, kept for upload memory).
fn device_type(types: &vk::PhysicalDeviceMemoryProperties, bits: u32) -> Option<u32> {
    let local = vk::MemoryPropertyFlags::DEVICE_LOCAL;
    memory_type(types, bits, local, vk::MemoryPropertyFlags::HOST_VISIBLE)
        .or_else(|| memory_type(types, bits, local, vk::MemoryPropertyFlags::empty()))
}

/// The host memory type among `bits` that is not the device's own, cached where it can be.
fn host_type(types: &vk::PhysicalDeviceMemoryProperties, bits: u32) -> Option<u32> {
    let host = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
    let local = vk::MemoryPropertyFlags::DEVICE_LOCAL;
    memory_type(
        types,
        bits,
        host | vk::MemoryPropertyFlags::HOST_CACHED,
        local,
    )
    .or_else(|| memory_type(types, bits, host, local))
}

/// The memory type among `bits` to upload through: the device's own, seen and kept coherent
/// by the host. Host memory the GPU pulls over the bus lost to it (docs/BENCHMARKS.md, issue
/// 11, session 48): the driver pins it as it makes it, and the copies take the frames' queue.
fn upload_type(types: &vk::PhysicalDeviceMemoryProperties, bits: u32) -> Option<u32> {
    let want = vk::MemoryPropertyFlags::DEVICE_LOCAL
        | vk::MemoryPropertyFlags::HOST_VISIBLE
        | vk::MemoryPropertyFlags::HOST_COHERENT;
    memory_type(types, bits, want, vk::MemoryPropertyFlags::empty())
}

/// A memory type among `bits` with every property of `want` and none of `avoid`.
fn memory_type(
    types: &vk::PhysicalDeviceMemoryProperties,
    bits: u32,
    want: vk::MemoryPropertyFlags,
    avoid: vk::MemoryPropertyFlags,
) -> Option<u32> {
    let unusable = vk::MemoryPropertyFlags::PROTECTED
        | vk::MemoryPropertyFlags::LAZILY_ALLOCATED
        | vk::MemoryPropertyFlags::DEVICE_COHERENT_AMD;
    let count = (types.memory_type_count as usize).min(types.memory_types.len());
    types.memory_types[..count]
        .iter()
        .enumerate()
        .position(|(i, t)| {
            bits & (1 << i) != 0
                && t.property_flags.contains(want)
                && !t.property_flags.intersects(avoid | unusable)
        })
        .map(|i| i as u32)
}

/// A buffer mapped for the CPU as long as it lives: in host memory the GPU reads over the bus,
/// or in the device's own memory that the host sees.
pub(crate) struct MappedBuffer {
    buffer: wgpu::Buffer,
    ptr: *mut u8,
    len: usize,
}

// SAFETY: the mapping is plain memory, reached only through `&mut self`.
unsafe impl Send for MappedBuffer {}

impl MappedBuffer {
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// The mapped bytes; the GPU must not be reading them meanwhile.
    pub fn bytes(&mut self) -> &mut [u8] {
        // SAFETY: `len` mapped bytes that stay mapped while the buffer lives (it is never
        // destroyed before `self` drops), borrowed exclusively.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

/// A buffer and its memory on their way to wgpu, destroyed if they do not get there.
struct Made<'a> {
    raw: &'a ash::Device,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
}

impl Drop for Made<'_> {
    fn drop(&mut self) {
        // SAFETY: both were made on this device and nothing else refers to them yet.
        unsafe {
            self.raw.destroy_buffer(self.buffer, None);
            if self.memory != vk::DeviceMemory::null() {
                self.raw.free_memory(self.memory, None);
            }
        }
    }
}

/// Vulkan's usage flags for a wgpu buffer usage without mapping (as wgpu-hal maps them).
fn vk_usage(usage: wgpu::BufferUsages) -> vk::BufferUsageFlags {
    use wgpu::BufferUsages as U;
    let pairs = [
        (U::COPY_SRC, vk::BufferUsageFlags::TRANSFER_SRC),
        (U::COPY_DST, vk::BufferUsageFlags::TRANSFER_DST),
        (U::UNIFORM, vk::BufferUsageFlags::UNIFORM_BUFFER),
        (U::STORAGE, vk::BufferUsageFlags::STORAGE_BUFFER),
        (U::INDEX, vk::BufferUsageFlags::INDEX_BUFFER),
        (U::VERTEX, vk::BufferUsageFlags::VERTEX_BUFFER),
        (U::INDIRECT, vk::BufferUsageFlags::INDIRECT_BUFFER),
    ];
    pairs
        .iter()
        .filter(|(w, _)| usage.contains(*w))
        .fold(vk::BufferUsageFlags::empty(), |f, (_, v)| f | *v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vk::MemoryPropertyFlags as F;

    fn types(flags: &[F]) -> vk::PhysicalDeviceMemoryProperties {
        let mut t = vk::PhysicalDeviceMemoryProperties {
            memory_type_count: flags.len() as u32,
            ..Default::default()
        };
        for (i, f) in flags.iter().enumerate() {
            t.memory_types[i].property_flags = *f;
        }
        t
    }

    #[test]
    fn buffers_take_device_memory_host_buffers_system_memory_and_uploads_the_bar() {
        let host = F::HOST_VISIBLE | F::HOST_COHERENT;
        // A discrete GPU with a resizable BAR.
        let discrete = types(&[
            F::DEVICE_LOCAL | F::PROTECTED,
            host | F::DEVICE_LOCAL,
            F::DEVICE_LOCAL,
            host,
            host | F::HOST_CACHED,
        ]);
        assert_eq!(device_type(&discrete, u32::MAX), Some(2));
        assert_eq!(host_type(&discrete, u32::MAX), Some(4));
        // Only the types a buffer may use count: the BAR, then none.
        assert_eq!(device_type(&discrete, 0b11), Some(1));
        assert_eq!(host_type(&discrete, 0b1000), Some(3));
        assert_eq!(host_type(&discrete, 0b111), None);
        assert_eq!(device_type(&discrete, 0b1), None);
        // A CPU or integrated GPU: all memory is the device's, none the host's alone.
        let unified = types(&[F::DEVICE_LOCAL | host | F::HOST_CACHED]);
        assert_eq!(device_type(&unified, u32::MAX), Some(0));
        assert_eq!(host_type(&unified, u32::MAX), None);
        // Upload memory: the device's own that the host sees (the BAR), never the host's.
        assert_eq!(upload_type(&discrete, u32::MAX), Some(1));
        assert_eq!(upload_type(&discrete, 0b11000), None);
        assert_eq!(upload_type(&discrete, 0b101), None);
        assert_eq!(upload_type(&unified, u32::MAX), Some(0));
    }
}
