// hbrdf_vk_runner — runs a compute shader over a float buffer with the plain
// Vulkan API, for conformance tests and benchmarks of generated shaders.
//
//   hbrdf_vk_runner SHADER.spv INPUT.bin OUTPUT.bin N_ITEMS OUT_FLOATS_PER_ITEM
//                   [--validation] [--repeat R] [--local-size 64]
//
// Binding 0: the input file as a read-only storage buffer; binding 1: the
// output (N_ITEMS * OUT_FLOATS_PER_ITEM floats). Dispatches ceil(N / local size)
// workgroups. With --validation the Khronos validation layer is enabled and any
// error or warning it reports makes the run fail. With --repeat R the dispatch
// is submitted R more times and the best time is printed ("best_ms <t>": host
// clock around submit + wait) for benchmarks; where the queue has timestamps,
// also the dispatch alone on the device's clock ("best_gpu_ms", "median_gpu_ms").
// Both buffers live in device-local memory, filled and read back through
// host-visible staging buffers outside the timed loop: on a discrete GPU the
// host-visible types are system memory across PCIe, which would time the bus
// rather than the shader. A discrete GPU is preferred over other devices. Half-precision shader
// arithmetic (shaderFloat16) is enabled where the device has it ("shader_float16 1" in the output).
// Pin lavapipe with VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json.
#include <vulkan/vulkan.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

int g_validation_messages = 0;

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                     VkDebugUtilsMessageTypeFlagsEXT,
                                                     const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
    if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        ++g_validation_messages;
        std::fprintf(stderr, "validation: %s\n", data->pMessage);
    }
    return VK_FALSE;
}

void check(VkResult r, const char* what) {
    if (r != VK_SUCCESS) throw std::runtime_error(std::string(what) + " failed (VkResult " + std::to_string(r) + ")");
}

std::vector<char> read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    return std::vector<char>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

struct Buffer {
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkDeviceSize size = 0;
};

// A buffer in the first memory type having all of `want` (staging: host-visible and coherent;
// storage: device-local, else any type the buffer accepts).
Buffer make_buffer(VkPhysicalDevice phys, VkDevice dev, VkDeviceSize size, VkBufferUsageFlags usage,
                   VkMemoryPropertyFlags want) {
    Buffer b;
    b.size = size;
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size;
    bi.usage = usage;
    bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    check(vkCreateBuffer(dev, &bi, nullptr, &b.buffer), "vkCreateBuffer");
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(dev, b.buffer, &req);
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(phys, &props);
    const bool staging = want & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
    uint32_t type = UINT32_MAX;
    for (uint32_t i = 0; i < props.memoryTypeCount && type == UINT32_MAX; ++i)
        if ((req.memoryTypeBits & (1u << i)) && (props.memoryTypes[i].propertyFlags & want) == want) type = i;
    for (uint32_t i = 0; i < props.memoryTypeCount && type == UINT32_MAX && !staging; ++i)
        if (req.memoryTypeBits & (1u << i)) type = i;
    if (type == UINT32_MAX) throw std::runtime_error(staging ? "no host-visible coherent memory type" : "no memory type");
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = type;
    check(vkAllocateMemory(dev, &ai, nullptr, &b.memory), "vkAllocateMemory");
    check(vkBindBufferMemory(dev, b.buffer, b.memory, 0), "vkBindBufferMemory");
    return b;
}

int run(int argc, char** argv) {
    if (argc < 6) {
        std::fprintf(stderr,
                     "usage: %s SHADER.spv INPUT.bin OUTPUT.bin N_ITEMS OUT_FLOATS_PER_ITEM [--validation] "
                     "[--repeat R] [--local-size 64]\n",
                     argv[0]);
        return 2;
    }
    const std::vector<char> spirv = read_file(argv[1]);
    std::vector<char> input = read_file(argv[2]);
    const std::string out_path = argv[3];
    const uint64_t n_items = std::strtoull(argv[4], nullptr, 10);
    const uint64_t out_floats = std::strtoull(argv[5], nullptr, 10);
    bool validation = false;
    int repeat = 0;
    uint32_t local_size = 64;
    for (int i = 6; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--validation")) validation = true;
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--local-size") && i + 1 < argc) local_size = uint32_t(std::atoi(argv[++i]));
        else throw std::runtime_error(std::string("unknown argument ") + argv[i]);
    }
    if (spirv.size() % 4 != 0 || spirv.empty()) throw std::runtime_error("SPIR-V size is not a multiple of 4");
    if (input.empty()) input.resize(4);

    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "hbrdf_vk_runner";
    app.apiVersion = VK_API_VERSION_1_1;
    const char* layers[] = {"VK_LAYER_KHRONOS_validation"};
    const char* extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ici.pApplicationInfo = &app;
    VkDebugUtilsMessengerCreateInfoEXT dbg{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    dbg.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    dbg.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                      VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    dbg.pfnUserCallback = on_validation_message;
    if (validation) {
        ici.enabledLayerCount = 1;
        ici.ppEnabledLayerNames = layers;
        ici.enabledExtensionCount = 1;
        ici.ppEnabledExtensionNames = extensions;
        ici.pNext = &dbg;  // also reports problems in instance creation itself
    }
    VkInstance instance;
    check(vkCreateInstance(&ici, nullptr, &instance), "vkCreateInstance");
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    if (validation) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
        if (!create) throw std::runtime_error("validation requested but VK_EXT_debug_utils is unavailable");
        check(create(instance, &dbg, nullptr, &messenger), "vkCreateDebugUtilsMessengerEXT");
    }

    uint32_t n_phys = 0;
    vkEnumeratePhysicalDevices(instance, &n_phys, nullptr);
    if (n_phys == 0) throw std::runtime_error("no Vulkan device (is mesa-vulkan-drivers installed?)");
    std::vector<VkPhysicalDevice> physs(n_phys);
    vkEnumeratePhysicalDevices(instance, &n_phys, physs.data());
    VkPhysicalDevice phys = physs[0];
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(phys, &props);
    for (VkPhysicalDevice p : physs) {  // a GPU machine may also list a CPU driver (lavapipe)
        VkPhysicalDeviceProperties pp;
        vkGetPhysicalDeviceProperties(p, &pp);
        if (pp.deviceType == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU && props.deviceType != pp.deviceType) {
            phys = p;
            props = pp;
        }
    }

    uint32_t n_families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(phys, &n_families, nullptr);
    std::vector<VkQueueFamilyProperties> families(n_families);
    vkGetPhysicalDeviceQueueFamilyProperties(phys, &n_families, families.data());
    uint32_t family = UINT32_MAX;
    for (uint32_t i = 0; i < n_families; ++i)
        if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
            family = i;
            break;
        }
    if (family == UINT32_MAX) throw std::runtime_error("no compute queue");
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = family;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    // Half-precision arithmetic in shaders (SPIR-V Float16: GL_EXT_shader_explicit_arithmetic_types_float16,
    // bench/shader_forms.py's packed-half forms) needs shaderFloat16 enabled at device creation; enabled
    // wherever the device has it (VK_KHR_shader_float16_int8, core in Vulkan 1.2; this instance asks for
    // 1.1, so through the extension). Buffers stay float32: no 16-bit storage is needed.
    uint32_t n_ext = 0;
    vkEnumerateDeviceExtensionProperties(phys, nullptr, &n_ext, nullptr);
    std::vector<VkExtensionProperties> exts(n_ext);
    vkEnumerateDeviceExtensionProperties(phys, nullptr, &n_ext, exts.data());
    const bool has_f16_ext = std::any_of(exts.begin(), exts.end(), [](const VkExtensionProperties& e) {
        return !std::strcmp(e.extensionName, VK_KHR_SHADER_FLOAT16_INT8_EXTENSION_NAME);
    });
    VkPhysicalDeviceShaderFloat16Int8FeaturesKHR f16{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_FLOAT16_INT8_FEATURES_KHR};
    const char* device_extensions[] = {VK_KHR_SHADER_FLOAT16_INT8_EXTENSION_NAME};
    if (has_f16_ext) {
        VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
        features.pNext = &f16;
        vkGetPhysicalDeviceFeatures2(phys, &features);
        f16.shaderInt8 = VK_FALSE;  // only what the half forms use
        if (f16.shaderFloat16) {
            dci.pNext = &f16;
            dci.enabledExtensionCount = 1;
            dci.ppEnabledExtensionNames = device_extensions;
        }
    }
    VkDevice dev;
    check(vkCreateDevice(phys, &dci, nullptr, &dev), "vkCreateDevice");
    VkQueue queue;
    vkGetDeviceQueue(dev, family, 0, &queue);

    const VkBufferUsageFlags copy = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    const VkDeviceSize out_size = std::max<VkDeviceSize>(4, n_items * out_floats * 4);
    Buffer in_buf = make_buffer(phys, dev, input.size(), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | copy,
                                VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    Buffer out_buf = make_buffer(phys, dev, out_size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | copy,
                                 VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    Buffer in_stage = make_buffer(phys, dev, input.size(), copy, host);
    Buffer out_stage = make_buffer(phys, dev, out_size, copy, host);
    void* mapped = nullptr;
    check(vkMapMemory(dev, in_stage.memory, 0, in_stage.size, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, input.data(), input.size());
    vkUnmapMemory(dev, in_stage.memory);

    VkDescriptorSetLayoutBinding bindings[2] = {};
    for (uint32_t i = 0; i < 2; ++i) {
        bindings[i].binding = i;
        bindings[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        bindings[i].descriptorCount = 1;
        bindings[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo dsl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dsl.bindingCount = 2;
    dsl.pBindings = bindings;
    VkDescriptorSetLayout set_layout;
    check(vkCreateDescriptorSetLayout(dev, &dsl, nullptr, &set_layout), "vkCreateDescriptorSetLayout");
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &set_layout;
    VkPipelineLayout pipe_layout;
    check(vkCreatePipelineLayout(dev, &pli, nullptr, &pipe_layout), "vkCreatePipelineLayout");
    VkShaderModuleCreateInfo smi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    smi.codeSize = spirv.size();
    smi.pCode = reinterpret_cast<const uint32_t*>(spirv.data());
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

    VkDescriptorPoolSize pool_size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = 1;
    dpi.poolSizeCount = 1;
    dpi.pPoolSizes = &pool_size;
    VkDescriptorPool pool;
    check(vkCreateDescriptorPool(dev, &dpi, nullptr, &pool), "vkCreateDescriptorPool");
    VkDescriptorSetAllocateInfo dsa{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    dsa.descriptorPool = pool;
    dsa.descriptorSetCount = 1;
    dsa.pSetLayouts = &set_layout;
    VkDescriptorSet set;
    check(vkAllocateDescriptorSets(dev, &dsa, &set), "vkAllocateDescriptorSets");
    VkDescriptorBufferInfo infos[2] = {{in_buf.buffer, 0, VK_WHOLE_SIZE}, {out_buf.buffer, 0, VK_WHOLE_SIZE}};
    VkWriteDescriptorSet writes[2] = {};
    for (uint32_t i = 0; i < 2; ++i) {
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = set;
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(dev, 2, writes, 0, nullptr);

    VkCommandPoolCreateInfo cpci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    cpci.queueFamilyIndex = family;
    VkCommandPool cmd_pool;
    check(vkCreateCommandPool(dev, &cpci, nullptr, &cmd_pool), "vkCreateCommandPool");
    VkCommandBufferAllocateInfo cbai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    cbai.commandPool = cmd_pool;
    cbai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cbai.commandBufferCount = 3;
    VkCommandBuffer cmds[3];  // upload, the timed dispatch, read-back
    check(vkAllocateCommandBuffers(dev, &cbai, cmds), "vkAllocateCommandBuffers");
    VkCommandBuffer upload = cmds[0], cmd = cmds[1], readback = cmds[2];
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    auto barrier = [](VkCommandBuffer c, VkPipelineStageFlags src, VkAccessFlags src_access, VkPipelineStageFlags dst,
                      VkAccessFlags dst_access) {
        VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        b.srcAccessMask = src_access;
        b.dstAccessMask = dst_access;
        vkCmdPipelineBarrier(c, src, dst, 0, 1, &b, 0, nullptr, 0, nullptr);
    };
    check(vkBeginCommandBuffer(upload, &begin), "vkBeginCommandBuffer");
    const VkBufferCopy in_copy{0, 0, in_buf.size};
    vkCmdCopyBuffer(upload, in_stage.buffer, in_buf.buffer, 1, &in_copy);
    barrier(upload, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
            VK_ACCESS_SHADER_READ_BIT);
    check(vkEndCommandBuffer(upload), "vkEndCommandBuffer");

    // Timestamps around the dispatch, where the queue family has them: the device's own clock,
    // without the submit and fence-wait latency that the host clock adds to a short dispatch.
    const bool timestamps = families[family].timestampValidBits > 0 && props.limits.timestampPeriod > 0;
    VkQueryPool queries = VK_NULL_HANDLE;
    if (timestamps) {
        VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qpi.queryCount = 2;
        check(vkCreateQueryPool(dev, &qpi, nullptr, &queries), "vkCreateQueryPool");
    }
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    if (timestamps) {
        vkCmdResetQueryPool(cmd, queries, 0, 2);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, 0);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipe_layout, 0, 1, &set, 0, nullptr);
    const uint64_t groups = (n_items + local_size - 1) / local_size;
    if (groups > props.limits.maxComputeWorkGroupCount[0])  // lavapipe: 65535, a GPU far more
        throw std::runtime_error("too many workgroups for this device: " + std::to_string(groups) + " > " +
                                 std::to_string(props.limits.maxComputeWorkGroupCount[0]));
    vkCmdDispatch(cmd, std::max<uint32_t>(uint32_t(groups), 1), 1, 1);
    if (timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 1);
    // The next repeat's dispatch and the read-back copy come after this dispatch's writes.
    barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
            VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    check(vkBeginCommandBuffer(readback, &begin), "vkBeginCommandBuffer");
    const VkBufferCopy out_copy{0, 0, out_buf.size};
    vkCmdCopyBuffer(readback, out_buf.buffer, out_stage.buffer, 1, &out_copy);
    barrier(readback, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_HOST_READ_BIT);
    check(vkEndCommandBuffer(readback), "vkEndCommandBuffer");

    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence;
    check(vkCreateFence(dev, &fci, nullptr, &fence), "vkCreateFence");
    auto submit = [&](VkCommandBuffer c) {
        VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
        si.commandBufferCount = 1;
        si.pCommandBuffers = &c;
        check(vkQueueSubmit(queue, 1, &si, fence), "vkQueueSubmit");
        check(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
        check(vkResetFences(dev, 1, &fence), "vkResetFences");
    };
    submit(upload);
    double best_ms = 1e30;
    std::vector<double> gpu_ms;
    const uint64_t ticks_mask =
        timestamps && families[family].timestampValidBits < 64 ? (uint64_t(1) << families[family].timestampValidBits) - 1
                                                               : ~uint64_t(0);
    for (int r = 0; r <= repeat; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        submit(cmd);
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        if (r > 0 || repeat == 0) {  // the first submit warms up when repeating
            best_ms = std::min(best_ms, ms);
            uint64_t ticks[2];
            if (timestamps &&
                vkGetQueryPoolResults(dev, queries, 0, 2, sizeof ticks, ticks, sizeof ticks[0],
                                      VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS)
                gpu_ms.push_back(double((ticks[1] - ticks[0]) & ticks_mask) * props.limits.timestampPeriod * 1e-6);
        }
    }
    submit(readback);
    check(vkMapMemory(dev, out_stage.memory, 0, out_stage.size, 0, &mapped), "vkMapMemory");
    {
        std::ofstream out(out_path, std::ios::binary);
        out.write(static_cast<const char*>(mapped), std::streamsize(n_items * out_floats * 4));
        if (!out) throw std::runtime_error("cannot write " + out_path);
    }
    vkUnmapMemory(dev, out_stage.memory);
    std::printf("device %s\nshader_float16 %d\nbest_ms %.4f\n", props.deviceName, int(f16.shaderFloat16), best_ms);
    if (!gpu_ms.empty()) {
        std::sort(gpu_ms.begin(), gpu_ms.end());
        std::printf("best_gpu_ms %.4f\nmedian_gpu_ms %.4f\n", gpu_ms.front(), gpu_ms[gpu_ms.size() / 2]);
    }

    vkDestroyFence(dev, fence, nullptr);
    if (queries) vkDestroyQueryPool(dev, queries, nullptr);
    vkDestroyCommandPool(dev, cmd_pool, nullptr);
    vkDestroyDescriptorPool(dev, pool, nullptr);
    vkDestroyPipeline(dev, pipeline, nullptr);
    vkDestroyShaderModule(dev, module, nullptr);
    vkDestroyPipelineLayout(dev, pipe_layout, nullptr);
    vkDestroyDescriptorSetLayout(dev, set_layout, nullptr);
    for (Buffer* b : {&in_buf, &out_buf, &in_stage, &out_stage}) {
        vkDestroyBuffer(dev, b->buffer, nullptr);
        vkFreeMemory(dev, b->memory, nullptr);
    }
    vkDestroyDevice(dev, nullptr);
    if (messenger) {
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
        if (destroy) destroy(instance, messenger, nullptr);
    }
    vkDestroyInstance(instance, nullptr);
    if (g_validation_messages) {
        std::fprintf(stderr, "%d validation message(s)\n", g_validation_messages);
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
