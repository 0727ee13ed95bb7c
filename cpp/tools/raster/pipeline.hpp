// hbrdf_raster — the graphics pipeline of a frame: an RGBA32F colour target and a reversed-Z
// D32 depth buffer in one render pass, the vertex layout of frame_scene.hpp, the camera (uniform,
// binding 0), the material table (storage, binding 1) and the lights (storage, binding 2) in one
// descriptor set, with a textured material's maps as combined image samplers (bindings 3, 4, ...),
// and the draw's material index as a push constant.
#pragma once

#include <vector>

#include "device.hpp"
#include "textures.hpp"

namespace hbrdf::raster {

/// The formats the frame is drawn into.
constexpr VkFormat kColorFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

/// Push constants of a draw: the material's row in the material table.
struct DrawConstants {
    int32_t material;
};

class FramePipeline {
public:
    /// Builds the targets (width x height), render pass, framebuffer, descriptor set (with
    /// `textures` sampled images) and the pipeline from the two SPIR-V modules (bytes; their size a
    /// multiple of 4).
    FramePipeline(const Device& device, uint32_t width, uint32_t height, const std::vector<char>& vertex_spirv,
                  const std::vector<char>& fragment_spirv, uint32_t textures = 0);
    ~FramePipeline();
    FramePipeline(const FramePipeline&) = delete;
    FramePipeline& operator=(const FramePipeline&) = delete;

    /// Points the descriptor set at the camera, material and light buffers and the textures (as
    /// many as the constructor was told, in binding order).
    void bind_buffers(const Buffer& camera, const Buffer& materials, const Buffer& lights,
                      const std::vector<Texture>& textures = {});
    /// Records the render pass's begin (clears colour to 0 and depth to 0, the far end of the
    /// reversed range), the pipeline and the set; the caller draws, then calls end().
    void begin(VkCommandBuffer cmd) const;
    void end(VkCommandBuffer cmd) const { vkCmdEndRenderPass(cmd); }
    VkPipelineLayout layout() const { return layout_; }
    /// The colour target, in TRANSFER_SRC_OPTIMAL after the render pass.
    VkImage color_image() const { return color_.image; }

private:
    const Device& device_;
    uint32_t width_, height_, textures_;
    Image color_, depth_;
    VkRenderPass pass_ = VK_NULL_HANDLE;
    VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
    VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
    VkDescriptorPool pool_ = VK_NULL_HANDLE;
    VkDescriptorSet set_ = VK_NULL_HANDLE;
    VkPipelineLayout layout_ = VK_NULL_HANDLE;
    VkPipeline pipeline_ = VK_NULL_HANDLE;
};

}  // namespace hbrdf::raster
