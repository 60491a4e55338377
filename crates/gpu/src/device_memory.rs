//! GPU buffers whose memory is made outside wgpu's allocator. wgpu makes every buffer's memory
//! under one lock, held while the driver makes it (~57 GB/s on the H100: 45 ms for a 2.5 GiB
//! chunk), and the render thread takes that lock for every buffer write; so a big buffer made
//! on any thread stalls the frames. On Vulkan the memory can be made directly on a thread of
//! its own and handed to wgpu whole ([`DirectAllocator`]).

use crate::GpuError;
use ash::vk;

/// Makes dedicated device memory for buffers through the Vulkan device itself.
#[derive(Clone)]
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

    /// A buffer of `size` bytes (device memory of its own, contents undefined) for `usage`,
    /// which must not ask for mapping.
    pub fn buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        let made = self.make(size, usage)?;
        let hal = {
            let made = std::mem::ManuallyDrop::new(made);
            // SAFETY: the buffer is bound to the whole of `memory`, which wgpu-hal frees when
            // the buffer is destroyed.
            unsafe {
                wgpu::hal::vulkan::Buffer::from_raw_managed(made.buffer, made.memory, 0, size)
            }
        };
        let desc = wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        };
        // SAFETY: made by this device for `desc`'s size and usage; wgpu takes the contents
        // as they are (every user of these buffers writes its slots before reading them).
        Ok(unsafe {
            self.device
                .create_buffer_from_hal::<wgpu::hal::api::Vulkan>(hal, &desc)
        })
    }

    fn make(&self, size: u64, usage: wgpu::BufferUsages) -> Result<Made<'_>, GpuError> {
        let failed = |what: &str, e: vk::Result| {
            if matches!(
                e,
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY
            ) {
                GpuError::OutOfMemory(format!("making {size} bytes of point memory"))
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
        let type_index = self.memory_type(needs.memory_type_bits).ok_or_else(|| {
            GpuError::Device(format!(
                "no device-local memory type for a buffer (types {:#x})",
                needs.memory_type_bits
            ))
        })?;
        let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().buffer(buffer);
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(needs.size)
            .memory_type_index(type_index)
            .push_next(&mut dedicated);
        // SAFETY: a valid allocate info for this device's memory types.
        made.memory = unsafe { self.raw.allocate_memory(&alloc, None) }
            .map_err(|e| failed("making device memory", e))?;
        // SAFETY: the memory was made for this buffer's requirements.
        unsafe { self.raw.bind_buffer_memory(buffer, made.memory, 0) }
            .map_err(|e| failed("binding device memory", e))?;
        Ok(made)
    }

    /// A device-local memory type among `bits`, not visible to the host where there is one
    /// (host-visible device memory is the resizable BAR's, kept for upload memory).
    fn memory_type(&self, bits: u32) -> Option<u32> {
        let unusable = vk::MemoryPropertyFlags::PROTECTED
            | vk::MemoryPropertyFlags::LAZILY_ALLOCATED
            | vk::MemoryPropertyFlags::DEVICE_COHERENT_AMD;
        let types = &self.types.memory_types[..self.types.memory_type_count as usize];
        let usable = |i: usize, t: &vk::MemoryType| {
            bits & (1 << i) != 0
                && t.property_flags
                    .contains(vk::MemoryPropertyFlags::DEVICE_LOCAL)
                && !t.property_flags.intersects(unusable)
        };
        let find = |host: bool| {
            types.iter().enumerate().position(|(i, t)| {
                usable(i, t)
                    && (host
                        || !t
                            .property_flags
                            .contains(vk::MemoryPropertyFlags::HOST_VISIBLE))
            })
        };
        find(false).or_else(|| find(true)).map(|i| i as u32)
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
