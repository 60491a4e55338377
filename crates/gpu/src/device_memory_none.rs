//! Where Vulkan is not the backend (browsers, Apple), every buffer is made through wgpu:
//! these types have no values.

use crate::GpuError;

pub(crate) enum DirectAllocator {}

impl DirectAllocator {
    pub fn new(_device: &wgpu::Device) -> Option<Self> {
        None
    }

    pub fn buffer(
        &self,
        _label: &str,
        _size: u64,
        _usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        match *self {}
    }

    pub fn host_buffer(
        &self,
        _label: &str,
        _size: u64,
        _usage: wgpu::BufferUsages,
    ) -> Result<Option<MappedBuffer>, GpuError> {
        match *self {}
    }

    pub fn upload_buffer(
        &self,
        _label: &str,
        _size: u64,
        _usage: wgpu::BufferUsages,
    ) -> Result<Option<MappedBuffer>, GpuError> {
        match *self {}
    }
}

pub(crate) enum MappedBuffer {}

impl MappedBuffer {
    pub fn buffer(&self) -> &wgpu::Buffer {
        match *self {}
    }

    pub fn bytes(&mut self) -> &mut [u8] {
        match *self {}
    }
}
