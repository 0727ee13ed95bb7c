// hbrdf_raster — the colour target read back (readback.hpp).
#include "readback.hpp"

namespace hbrdf::raster {

render::Image read_color(const Device& device, VkImage color, uint32_t width, uint32_t height) {
    const VkDeviceSize size = VkDeviceSize(width) * height * 4 * sizeof(float);
    Buffer host = device.make_buffer(size, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                     VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    VkCommandBuffer cmd = device.begin_commands();
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {width, height, 1};
    vkCmdCopyImageToBuffer(cmd, color, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.buffer, 1, &region);
    VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0,
                         nullptr);
    device.submit_and_wait(cmd);
    device.free_commands(cmd);
    void* mapped = nullptr;
    check(vkMapMemory(device.handle(), host.memory, 0, size, 0, &mapped), "vkMapMemory");
    const float* rgba = static_cast<const float*>(mapped);
    render::Image image{int(width), int(height)};
    for (std::size_t i = 0, n = std::size_t(width) * height; i < n; ++i)
        for (int c = 0; c < 3; ++c) image.rgb[3 * i + std::size_t(c)] = rgba[4 * i + std::size_t(c)];
    vkUnmapMemory(device.handle(), host.memory);
    device.destroy(host);
    return image;
}

}  // namespace hbrdf::raster
