// hbrdf_raster — a textured material's maps as sampled images (textures.hpp).
#include "textures.hpp"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

#include "hybridbrdf/render/image.hpp"

namespace hbrdf::raster {
namespace {

constexpr uint32_t kMaxSide = 16384;

void to_layout(VkCommandBuffer cmd, VkImage image, uint32_t levels, VkImageLayout from, VkImageLayout to,
               VkAccessFlags src_access, VkAccessFlags dst_access, VkPipelineStageFlags src, VkPipelineStageFlags dst) {
    VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    b.oldLayout = from;
    b.newLayout = to;
    b.srcAccessMask = src_access;
    b.dstAccessMask = dst_access;
    b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, levels, 0, 1};
    vkCmdPipelineBarrier(cmd, src, dst, 0, 0, nullptr, 0, nullptr, 1, &b);
}

}  // namespace

Texture load_texture(const Device& device, const std::string& path) {
    render::check_input_file(path, "texture file");
    std::ifstream in(path, std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    uint32_t head[5];
    if (bytes.size() < 24 || std::memcmp(bytes.data(), "HBTX", 4))
        throw render::FileError(path, "not a texture file of hbrdf raster (no HBTX header)");
    std::memcpy(head, bytes.data() + 4, sizeof head);
    const uint32_t width = head[0], height = head[1], levels = head[2];
    if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide || levels < 1 || levels > 15 || head[3] > 1 ||
        head[4] > 1)
        throw render::FileError(path, "texture header out of range");
    std::vector<VkBufferImageCopy> regions;
    std::size_t offset = 24;
    for (uint32_t l = 0; l < levels; ++l) {
        const uint32_t w = std::max(1u, width >> l), h = std::max(1u, height >> l);
        VkBufferImageCopy r{};
        r.bufferOffset = offset;
        r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1};
        r.imageExtent = {w, h, 1};
        regions.push_back(r);
        offset += std::size_t(w) * h * 4;
    }
    if (offset != bytes.size())
        throw render::FileError(path, "holds " + std::to_string(bytes.size()) + " bytes; its header says " +
                                          std::to_string(offset));
    const VkFormat format = head[3] ? VK_FORMAT_R8G8B8A8_SRGB : VK_FORMAT_R8G8B8A8_UNORM;
    Texture t;
    t.image = device.make_image(width, height, format, VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                                VK_IMAGE_ASPECT_COLOR_BIT, levels);
    const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    Buffer stage = device.make_buffer(bytes.size(), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
    void* mapped = nullptr;
    check(vkMapMemory(device.handle(), stage.memory, 0, stage.size, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, bytes.data(), bytes.size());
    vkUnmapMemory(device.handle(), stage.memory);
    VkCommandBuffer cmd = device.begin_commands();
    to_layout(cmd, t.image.image, levels, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
              VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    vkCmdCopyBufferToImage(cmd, stage.buffer, t.image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, uint32_t(regions.size()),
                           regions.data());
    to_layout(cmd, t.image.image, levels, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
              VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
              VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
    device.submit_and_wait(cmd);
    device.free_commands(cmd);
    device.destroy(stage);
    VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    si.magFilter = si.minFilter = VK_FILTER_LINEAR;
    si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_LINEAR;
    si.addressModeU = si.addressModeV = si.addressModeW =
        head[4] ? VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE : VK_SAMPLER_ADDRESS_MODE_REPEAT;
    si.maxLod = float(levels - 1);
    check(vkCreateSampler(device.handle(), &si, nullptr, &t.sampler), "vkCreateSampler");
    return t;
}

void destroy(const Device& device, Texture& texture) {
    if (texture.sampler) vkDestroySampler(device.handle(), texture.sampler, nullptr);
    device.destroy(texture.image);
    texture.sampler = VK_NULL_HANDLE;
}

}  // namespace hbrdf::raster
