// hbrdf_raster and hbrdf_vk_runner — the Vulkan device: instance (with the Khronos validation layer
// on request), a graphics or compute queue, buffers and images in the memory types they need,
// one-shot submissions. What a headless renderer or compute runner needs and nothing else: no
// surface, no swapchain.
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <stdexcept>
#include <string>

namespace hbrdf::raster {

/// Throws std::runtime_error "<what> failed (VkResult N)" unless r is VK_SUCCESS.
void check(VkResult r, const char* what);

struct Buffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkDeviceSize size = 0;
};

struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
};

/// One logical device with one queue of the first family having `queue` (graphics for the raster
/// frame, compute for the runner). A discrete GPU is preferred over other devices (a GPU machine
/// may also list lavapipe). Two optional features are enabled wherever the device has them:
/// shaderFloat16 (VK_KHR_shader_float16_int8: half arithmetic in shaders) and
/// textureCompressionBC (sampling BC1-BC7 images). Destroys everything it made in its destructor.
class Device {
public:
    /// `bc` false leaves textureCompressionBC off even where the device has it (hbrdf_vk_runner
    /// --without-bc: how a device without BC sampling refuses a BC map, testable on one that has it).
    explicit Device(bool validation, VkQueueFlags queue = VK_QUEUE_GRAPHICS_BIT, const char* app = "hbrdf_raster",
                    bool bc = true);
    ~Device();
    Device(const Device&) = delete;
    Device& operator=(const Device&) = delete;

    VkDevice handle() const { return device_; }
    const VkPhysicalDeviceProperties& properties() const { return props_; }
    /// Bits of the queue's timestamps (0: none).
    uint32_t timestamp_bits() const { return timestamp_bits_; }
    /// Whether shaderFloat16 and textureCompressionBC were enabled (the device has them).
    bool shader_float16() const { return shader_float16_; }
    bool texture_compression_bc() const { return texture_compression_bc_; }
    /// What optimally tiled images of `format` support on this device (sampling, linear filtering).
    VkFormatFeatureFlags format_features(VkFormat format) const;
    /// Messages of warning or error severity the validation layer reported so far, in this process
    /// (static: a caller counts those of a device's destruction too).
    static int validation_messages();

    /// A buffer in the first memory type having all of `want` (host-visible staging buffers:
    /// coherent too; device buffers: device-local, else any type the buffer accepts).
    Buffer make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, VkMemoryPropertyFlags want) const;
    /// A device-local buffer holding `bytes`, copied through a staging buffer.
    Buffer upload(const void* bytes, std::size_t size, VkBufferUsageFlags usage) const;
    /// A 2D device-local image of `levels` mip levels with a view of `aspect` over all of them.
    Image make_image(uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage,
                     VkImageAspectFlags aspect, uint32_t levels = 1) const;
    void destroy(Buffer& b) const;
    void destroy(Image& i) const;

    /// A primary command buffer from the device's pool, begun for recording.
    VkCommandBuffer begin_commands() const;
    /// Ends (if `end`) and submits `cmd`, then waits for the queue to finish it.
    void submit_and_wait(VkCommandBuffer cmd, bool end = true) const;
    void free_commands(VkCommandBuffer cmd) const;

private:
    uint32_t memory_type(uint32_t allowed, VkMemoryPropertyFlags want, bool strict) const;

    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    VkPhysicalDevice physical_ = VK_NULL_HANDLE;
    VkPhysicalDeviceProperties props_{};
    VkPhysicalDeviceMemoryProperties memory_{};
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;
    uint32_t family_ = 0, timestamp_bits_ = 0;
    bool shader_float16_ = false, texture_compression_bc_ = false;
};

}  // namespace hbrdf::raster
