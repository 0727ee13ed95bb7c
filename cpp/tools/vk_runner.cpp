// hbrdf_vk_runner — runs a compute shader over a float buffer with the plain
// Vulkan API, for conformance tests and benchmarks of generated shaders.
//
//   hbrdf_vk_runner SHADER.spv INPUT.bin OUTPUT.bin N_ITEMS OUT_FLOATS_PER_ITEM
//                   [--validation] [--repeat R] [--local-size 64]
//                   [--texture MAP.ktx2|MAP.hbtx]... [--separate-sampler] [--clamp] [--nearest-mip]
//                   [--without-bc]
//
// Binding 0: the input file as a read-only storage buffer; binding 1: the
// output (N_ITEMS * OUT_FLOATS_PER_ITEM floats). Dispatches ceil(N / local size)
// workgroups. With --validation the Khronos validation layer is enabled and any
// error or warning it reports makes the run fail. With --repeat R the dispatch
// is submitted R more times and the best time is printed ("best_ms <t>": host
// clock around submit + wait; "best_cpu_ms": the process's CPU time around it,
// lavapipe's threads included) for benchmarks; where the queue has timestamps,
// also the dispatch alone on the device's clock ("best_gpu_ms", "median_gpu_ms").
// Both buffers live in device-local memory, filled and read back through
// host-visible staging buffers outside the timed loop: on a discrete GPU the
// host-visible types are system memory across PCIe, which would time the bus
// rather than the shader. A discrete GPU is preferred over other devices. Half-precision shader
// arithmetic (shaderFloat16) is enabled where the device has it ("shader_float16 1" in the output).
//
// Textures (a textured material's maps, docs/CODEGEN.md): each --texture, in order, a sampled image
// with its mip chain (raster/textures.hpp: a KTX2 file in its own format, BC blocks included, or
// hbrdf raster's HBTX file of 8-bit RGBA levels), linear filtering between texels and between mip
// levels (--nearest-mip: the nearest level), repeat addressing (--clamp: clamp to edge; an HBTX
// file's header says its own). Bound as combined image samplers at bindings 2, 3, ... (GLSL's
// sampler2D); with --separate-sampler, as HLSL, Slang and WGSL declare them: one sampler at binding
// 2 (the first texture's), the images at bindings 3, 4, ... A KTX2 format the device cannot sample
// with linear filtering (a BC format without textureCompressionBC) is refused in one line naming
// the file and the device; --without-bc creates the device without textureCompressionBC, as one
// lacking it (the refusal, tested on a device that has it). Pin lavapipe with VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json.
#include <vulkan/vulkan.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "raster/device.hpp"
#ifdef HBRDF_VK_RUNNER_TEXTURES
#include "raster/textures.hpp"
#endif

namespace {

using hbrdf::raster::Buffer;
using hbrdf::raster::check;
using hbrdf::raster::Device;

std::vector<char> read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    return std::vector<char>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

struct Args {
    std::vector<char> spirv, input;
    std::string out_path;
    uint64_t n_items = 0, out_floats = 0;
    bool validation = false, separate_sampler = false, clamp = false, nearest_mip = false, without_bc = false;
    int repeat = 0;
    uint32_t local_size = 64;
    std::vector<std::string> textures;
};

Args parse(int argc, char** argv) {
    Args a;
    a.spirv = read_file(argv[1]);
    a.input = read_file(argv[2]);
    a.out_path = argv[3];
    a.n_items = std::strtoull(argv[4], nullptr, 10);
    a.out_floats = std::strtoull(argv[5], nullptr, 10);
    for (int i = 6; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--validation")) a.validation = true;
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) a.repeat = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--local-size") && i + 1 < argc) a.local_size = uint32_t(std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--texture") && i + 1 < argc) a.textures.push_back(argv[++i]);
        else if (!std::strcmp(argv[i], "--separate-sampler")) a.separate_sampler = true;
        else if (!std::strcmp(argv[i], "--clamp")) a.clamp = true;
        else if (!std::strcmp(argv[i], "--nearest-mip")) a.nearest_mip = true;
        else if (!std::strcmp(argv[i], "--without-bc")) a.without_bc = true;
        else throw std::runtime_error(std::string("unknown argument ") + argv[i]);
    }
    if (a.spirv.size() % 4 != 0 || a.spirv.empty()) throw std::runtime_error("SPIR-V size is not a multiple of 4");
    if (a.input.empty()) a.input.resize(4);
#ifndef HBRDF_VK_RUNNER_TEXTURES
    if (!a.textures.empty()) throw std::runtime_error("--texture: built without the renderer library (hybridbrdf_render)");
#endif
    return a;
}

#ifdef HBRDF_VK_RUNNER_TEXTURES
using hbrdf::raster::Texture;
#else
struct Texture {
    VkImageView view() const { return VK_NULL_HANDLE; }
};
#endif

// The descriptor set of the run: the two storage buffers, then the textures as run() describes.
struct Bindings {
    std::vector<VkDescriptorSetLayoutBinding> layout;
    std::vector<VkDescriptorImageInfo> images;
};

Bindings describe(const Args& a, const std::vector<Texture>& textures) {
    Bindings b;
    auto add = [&](uint32_t binding, VkDescriptorType type) {
        VkDescriptorSetLayoutBinding l{};
        l.binding = binding;
        l.descriptorType = type;
        l.descriptorCount = 1;
        l.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
        b.layout.push_back(l);
    };
    add(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
    add(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
#ifdef HBRDF_VK_RUNNER_TEXTURES
    const uint32_t first = a.separate_sampler ? 3 : 2;
    if (a.separate_sampler && !textures.empty()) {
        add(2, VK_DESCRIPTOR_TYPE_SAMPLER);
        b.images.push_back({textures[0].sampler, VK_NULL_HANDLE, VK_IMAGE_LAYOUT_UNDEFINED});
    }
    for (uint32_t j = 0; j < textures.size(); ++j) {
        add(first + j, a.separate_sampler ? VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE : VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER);
        b.images.push_back({a.separate_sampler ? VK_NULL_HANDLE : textures[j].sampler, textures[j].image.view,
                            VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
    }
#else
    (void)a;
    (void)textures;
#endif
    return b;
}

// This process's CPU time in ms: on lavapipe, whose threads are this process's, the work a dispatch
// costs whatever else the machine runs.
double process_cpu_ms() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

void barrier(VkCommandBuffer c, VkPipelineStageFlags src, VkAccessFlags src_access, VkPipelineStageFlags dst,
             VkAccessFlags dst_access) {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = src_access;
    b.dstAccessMask = dst_access;
    vkCmdPipelineBarrier(c, src, dst, 0, 1, &b, 0, nullptr, 0, nullptr);
}

int run(int argc, char** argv) {
    if (argc < 6) {
        std::fprintf(stderr,
                     "usage: %s SHADER.spv INPUT.bin OUTPUT.bin N_ITEMS OUT_FLOATS_PER_ITEM [--validation] "
                     "[--repeat R] [--local-size 64] [--texture MAP.ktx2|MAP.hbtx]... [--separate-sampler] [--clamp] "
                     "[--nearest-mip] [--without-bc]\n",
                     argv[0]);
        return 2;
    }
    const Args a = parse(argc, argv);
    auto owner = std::make_unique<Device>(a.validation, VK_QUEUE_COMPUTE_BIT, "hbrdf_vk_runner", !a.without_bc);
    Device& device = *owner;
    const VkDevice dev = device.handle();
    const VkPhysicalDeviceProperties& props = device.properties();

    std::vector<Texture> textures;
#ifdef HBRDF_VK_RUNNER_TEXTURES
    for (const std::string& path : a.textures)
        textures.push_back(hbrdf::raster::load_texture(device, path, {a.clamp, a.nearest_mip}));
#endif
    const VkBufferUsageFlags copy = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    const VkDeviceSize out_size = std::max<VkDeviceSize>(4, a.n_items * a.out_floats * 4);
    Buffer in_buf = device.upload(a.input.data(), a.input.size(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    Buffer out_buf = device.make_buffer(out_size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | copy, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    Buffer out_stage = device.make_buffer(out_size, copy, host);

    const Bindings bindings = describe(a, textures);
    VkDescriptorSetLayoutCreateInfo dsl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dsl.bindingCount = uint32_t(bindings.layout.size());
    dsl.pBindings = bindings.layout.data();
    VkDescriptorSetLayout set_layout;
    check(vkCreateDescriptorSetLayout(dev, &dsl, nullptr, &set_layout), "vkCreateDescriptorSetLayout");
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &set_layout;
    VkPipelineLayout pipe_layout;
    check(vkCreatePipelineLayout(dev, &pli, nullptr, &pipe_layout), "vkCreatePipelineLayout");
    VkShaderModuleCreateInfo smi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    smi.codeSize = a.spirv.size();
    smi.pCode = reinterpret_cast<const uint32_t*>(a.spirv.data());
    VkShaderModule module;
    check(vkCreateShaderModule(dev, &smi, nullptr, &module), "vkCreateShaderModule");
    VkComputePipelineCreateInfo cpi{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    cpi.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cpi.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cpi.stage.module = module;
    cpi.stage.pName = "main";
    cpi.layout = pipe_layout;
    VkPipeline pipeline;
    check(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &cpi, nullptr, &pipeline), "vkCreateComputePipelines");

    std::vector<VkDescriptorPoolSize> pool_sizes;
    for (const VkDescriptorSetLayoutBinding& l : bindings.layout) pool_sizes.push_back({l.descriptorType, 1});
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = 1;
    dpi.poolSizeCount = uint32_t(pool_sizes.size());
    dpi.pPoolSizes = pool_sizes.data();
    VkDescriptorPool pool;
    check(vkCreateDescriptorPool(dev, &dpi, nullptr, &pool), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo dsa{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    dsa.descriptorPool = pool;
    dsa.descriptorSetCount = 1;
    dsa.pSetLayouts = &set_layout;
    VkDescriptorSet set;
    check(vkAllocateDescriptorSets(dev, &dsa, &set), "vkAllocateDescriptorSets");
    VkDescriptorBufferInfo infos[2] = {{in_buf.buffer, 0, VK_WHOLE_SIZE}, {out_buf.buffer, 0, VK_WHOLE_SIZE}};
    std::vector<VkWriteDescriptorSet> writes(bindings.layout.size());
    for (std::size_t i = 0; i < writes.size(); ++i) {
        writes[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        writes[i].dstSet = set;
        writes[i].dstBinding = bindings.layout[i].binding;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = bindings.layout[i].descriptorType;
        if (i < 2) writes[i].pBufferInfo = &infos[i];
        else writes[i].pImageInfo = &bindings.images[i - 2];
    }
    vkUpdateDescriptorSets(dev, uint32_t(writes.size()), writes.data(), 0, nullptr);

    // Timestamps around the dispatch, where the queue family has them: the device's own clock,
    // without the submit and fence-wait latency that the host clock adds to a short dispatch.
    const bool timestamps = device.timestamp_bits() > 0;
    VkQueryPool queries = VK_NULL_HANDLE;
    if (timestamps) {
        VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qpi.queryCount = 2;
        check(vkCreateQueryPool(dev, &qpi, nullptr, &queries), "vkCreateQueryPool");
    }
    const uint64_t groups = (a.n_items + a.local_size - 1) / a.local_size;
    if (groups > props.limits.maxComputeWorkGroupCount[0])  // lavapipe: 65535, a GPU far more
        throw std::runtime_error("too many workgroups for this device: " + std::to_string(groups) + " > " +
                                 std::to_string(props.limits.maxComputeWorkGroupCount[0]));
    VkCommandBuffer cmd = device.begin_commands();  // the timed dispatch, submitted 1 + R times
    if (timestamps) {
        vkCmdResetQueryPool(cmd, queries, 0, 2);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, 0);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe_layout, 0, 1, &set, 0, nullptr);
    vkCmdDispatch(cmd, std::max<uint32_t>(uint32_t(groups), 1), 1, 1);
    if (timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 1);
    // The next repeat's dispatch and the read-back copy come after this dispatch's writes.
    barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");

    double best_ms = 1e30, best_cpu_ms = 1e30;
    std::vector<double> gpu_ms;
    const uint32_t bits = device.timestamp_bits();
    const uint64_t ticks_mask = timestamps && bits < 64 ? (uint64_t(1) << bits) - 1 : ~uint64_t(0);
    for (int r = 0; r <= a.repeat; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        const double cpu0 = process_cpu_ms();
        device.submit_and_wait(cmd, false);
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const double cpu_ms = process_cpu_ms() - cpu0;
        if (r > 0 || a.repeat == 0) {  // the first submit warms up when repeating
            best_ms = std::min(best_ms, ms);
            best_cpu_ms = std::min(best_cpu_ms, cpu_ms);
            uint64_t ticks[2];
            if (timestamps &&
                vkGetQueryPoolResults(dev, queries, 0, 2, sizeof ticks, ticks, sizeof ticks[0],
                                      VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS)
                gpu_ms.push_back(double((ticks[1] - ticks[0]) & ticks_mask) * props.limits.timestampPeriod * 1e-6);
        }
    }
    VkCommandBuffer readback = device.begin_commands();
    const VkBufferCopy out_copy{0, 0, out_buf.size};
    vkCmdCopyBuffer(readback, out_buf.buffer, out_stage.buffer, 1, &out_copy);
    barrier(readback, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_HOST_READ_BIT);
    device.submit_and_wait(readback);
    void* mapped = nullptr;
    check(vkMapMemory(dev, out_stage.memory, 0, out_stage.size, 0, &mapped), "vkMapMemory");
    {
        std::ofstream out(a.out_path, std::ios::binary);
        out.write(static_cast<const char*>(mapped), std::streamsize(a.n_items * a.out_floats * 4));
        if (!out) throw std::runtime_error("cannot write " + a.out_path);
    }
    vkUnmapMemory(dev, out_stage.memory);
    std::printf("device %s\nshader_float16 %d\nbest_ms %.4f\nbest_cpu_ms %.4f\n", props.deviceName,
                int(device.shader_float16()), best_ms, best_cpu_ms);
    if (!gpu_ms.empty()) {
        std::sort(gpu_ms.begin(), gpu_ms.end());
        std::printf("best_gpu_ms %.4f\nmedian_gpu_ms %.4f\n", gpu_ms.front(), gpu_ms[gpu_ms.size() / 2]);
    }

    device.free_commands(cmd);
    device.free_commands(readback);
    if (queries) vkDestroyQueryPool(dev, queries, nullptr);
    vkDestroyDescriptorPool(dev, pool, nullptr);
    vkDestroyPipeline(dev, pipeline, nullptr);
    vkDestroyShaderModule(dev, module, nullptr);
    vkDestroyPipelineLayout(dev, pipe_layout, nullptr);
    vkDestroyDescriptorSetLayout(dev, set_layout, nullptr);
#ifdef HBRDF_VK_RUNNER_TEXTURES
    for (Texture& t : textures) hbrdf::raster::destroy(device, t);
#endif
    for (Buffer* b : {&in_buf, &out_buf, &out_stage}) device.destroy(*b);
    owner.reset();  // what the layer says of the device's destruction counts too
    if (Device::validation_messages()) {
        std::fprintf(stderr, "%d validation message(s)\n", Device::validation_messages());
        return 3;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "hbrdf_vk_runner: %s\n", e.what());
        return 1;
    }
}
