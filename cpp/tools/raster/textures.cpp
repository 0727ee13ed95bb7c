// hbrdf_raster — a textured material's maps as sampled images (textures.hpp).
#include "textures.hpp"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

#include "hybridbrdf/render/image.hpp"
#include "hybridbrdf/render/gltf_material.hpp"
#include "hybridbrdf/render/ktx2.hpp"

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

// Every level of `bytes` (the regions' offsets into it) into a new image of `format`, left in
// SHADER_READ_ONLY_OPTIMAL.
Image upload_levels(const Device& device, VkFormat format, uint32_t width, uint32_t height,
                    const std::vector<VkBufferImageCopy>& regions, const unsigned char* bytes, std::size_t size) {
    const auto levels = uint32_t(regions.size());
    Image image = device.make_image(width, height, format, VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                                    VK_IMAGE_ASPECT_COLOR_BIT, levels);
    const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    Buffer stage = device.make_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
    void* mapped = nullptr;
    check(vkMapMemory(device.handle(), stage.memory, 0, stage.size, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, bytes, size);
    vkUnmapMemory(device.handle(), stage.memory);
    VkCommandBuffer cmd = device.begin_commands();
    to_layout(cmd, image.image, levels, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
              VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    vkCmdCopyBufferToImage(cmd, stage.buffer, image.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, levels, regions.data());
    // Read by fragment shaders (the raster frame) or compute shaders (the runner).
    to_layout(cmd, image.image, levels, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
              VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
              VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    device.submit_and_wait(cmd);
    device.free_commands(cmd);
    device.destroy(stage);
    return image;
}

VkSamplerAddressMode address_mode(render::GltfWrap w) {
    switch (w) {
        case render::GltfWrap::ClampToEdge: return VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
        case render::GltfWrap::MirroredRepeat: return VK_SAMPLER_ADDRESS_MODE_MIRRORED_REPEAT;
        default: return VK_SAMPLER_ADDRESS_MODE_REPEAT;
    }
}

}  // namespace

Texture upload_gltf_texture(const Device& device, const render::GltfTexture& gt) {
    const render::GltfImage& im = *gt.image;
    const auto width = uint32_t(im.width), height = uint32_t(im.height);
    // glTF minFilter 9984-9987 asks for a mip chain: the tracer's own levels (gltf_mip_chain), built
    // here only for a texture that arrives without them, so both read the same texels.
    std::shared_ptr<const std::vector<render::GltfImage>> mips;
    if (render::gltf_mipmapped(gt.min_filter))
        mips = gt.mips ? gt.mips : std::make_shared<const std::vector<render::GltfImage>>(render::gltf_mip_chain(im, gt.srgb));
    std::vector<const render::GltfImage*> chain{&im};
    if (mips)
        for (const render::GltfImage& level : *mips) chain.push_back(&level);
    const auto levels = uint32_t(chain.size());
    std::vector<VkBufferImageCopy> regions;
    std::vector<unsigned char> bytes;
    for (uint32_t l = 0; l < levels; ++l) {
        VkBufferImageCopy r{};
        r.bufferOffset = bytes.size();  // RGBA8: every offset a multiple of 4
        r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1};
        r.imageExtent = {uint32_t(chain[l]->width), uint32_t(chain[l]->height), 1};
        regions.push_back(r);
        bytes.insert(bytes.end(), chain[l]->rgba.begin(), chain[l]->rgba.end());
    }
    Texture t;
    t.image = upload_levels(device, gt.srgb ? VK_FORMAT_R8G8B8A8_SRGB : VK_FORMAT_R8G8B8A8_UNORM, width, height, regions,
                            bytes.data(), bytes.size());
    VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    si.magFilter = gt.nearest ? VK_FILTER_NEAREST : VK_FILTER_LINEAR;
    // 9728 NEAREST, 9729 LINEAR, 9984 NEAREST_MIPMAP_NEAREST, 9985 LINEAR_MIPMAP_NEAREST,
    // 9986 NEAREST_MIPMAP_LINEAR, 9987 LINEAR_MIPMAP_LINEAR
    const int m = gt.min_filter;
    si.minFilter = (m == 9728 || m == 9984 || m == 9986) ? VK_FILTER_NEAREST : VK_FILTER_LINEAR;
    si.mipmapMode = (m == 9986 || m == 9987) ? VK_SAMPLER_MIPMAP_MODE_LINEAR : VK_SAMPLER_MIPMAP_MODE_NEAREST;
    si.addressModeU = address_mode(gt.wrap_s);
    si.addressModeV = address_mode(gt.wrap_t);
    si.addressModeW = VK_SAMPLER_ADDRESS_MODE_REPEAT;
    si.maxLod = float(levels - 1);
    check(vkCreateSampler(device.handle(), &si, nullptr, &t.sampler), "vkCreateSampler");
    return t;
}

Texture blank_texture(const Device& device) {
    render::GltfTexture gt;
    auto im = std::make_shared<render::GltfImage>();
    im->width = im->height = 1;
    im->rgba = {255, 255, 255, 255};
    gt.image = im;
    gt.min_filter = 9729;
    return upload_gltf_texture(device, gt);
}

namespace {

// A sampler over a texture's levels of `clamp` addressing, linear in a level, linear or nearest
// between levels.
VkSampler folder_sampler(const Device& device, uint32_t levels, bool clamp, bool nearest_mip) {
    VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    si.magFilter = si.minFilter = VK_FILTER_LINEAR;
    si.mipmapMode = nearest_mip ? VK_SAMPLER_MIPMAP_MODE_NEAREST : VK_SAMPLER_MIPMAP_MODE_LINEAR;
    si.addressModeU = si.addressModeV = si.addressModeW =
        clamp ? VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE : VK_SAMPLER_ADDRESS_MODE_REPEAT;
    si.maxLod = float(levels - 1);
    VkSampler sampler = VK_NULL_HANDLE;
    check(vkCreateSampler(device.handle(), &si, nullptr, &sampler), "vkCreateSampler");
    return sampler;
}

Texture load_ktx2_texture(const Device& device, const std::string& path, const Sampling& sampling) {
    const render::Ktx2Texture k = render::read_ktx2(path);  // bounded and checked, its words
    const auto format = VkFormat(k.vk_format);
    const bool block = k.format_name.rfind("BC", 0) == 0;
    const std::string device_name = device.properties().deviceName;
    if (block && !device.texture_compression_bc())
        throw render::FileError(path, k.format_name + " needs textureCompressionBC, which the device " + device_name +
                                          " lacks");
    const VkFormatFeatureFlags need = VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
    if ((device.format_features(format) & need) != need)
        throw render::FileError(path, "the device " + device_name + " cannot sample " + k.format_name +
                                          " images with linear filtering");
    std::vector<VkBufferImageCopy> regions;
    std::vector<unsigned char> bytes;
    for (uint32_t l = 0; l < k.levels.size(); ++l) {
        const render::Ktx2Level& level = k.levels[l];
        VkBufferImageCopy r{};
        r.bufferOffset = bytes.size();  // each level's size a multiple of its block's bytes (8 or 16) or texel's
        r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1};
        r.imageExtent = {level.width, level.height, 1};  // a partial edge block reaches the level's edge
        regions.push_back(r);
        bytes.insert(bytes.end(), level.stored.begin(), level.stored.end());
    }
    Texture t;
    t.image = upload_levels(device, format, k.width, k.height, regions, bytes.data(), bytes.size());
    t.sampler = folder_sampler(device, uint32_t(regions.size()), sampling.clamp, sampling.nearest_mip);
    return t;
}

}  // namespace

Texture load_texture(const Device& device, const std::string& path, const Sampling& sampling) {
    render::check_input_file(path, "texture file");
    if (path.size() >= 5 && path.compare(path.size() - 5, 5, ".ktx2") == 0) return load_ktx2_texture(device, path, sampling);
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
        r.bufferOffset = offset - 24;
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
    t.image = upload_levels(device, format, width, height, regions, reinterpret_cast<const unsigned char*>(bytes.data()) + 24,
                            bytes.size() - 24);
    t.sampler = folder_sampler(device, levels, head[4] == 1, sampling.nearest_mip);
    return t;
}

void destroy(const Device& device, Texture& texture) {
    if (texture.sampler) vkDestroySampler(device.handle(), texture.sampler, nullptr);
    device.destroy(texture.image);
    texture.sampler = VK_NULL_HANDLE;
}

}  // namespace hbrdf::raster
