// hbrdf_raster and hbrdf_vk_runner — the Vulkan device (device.hpp).
#include "device.hpp"

#include <cstdio>
#include <cstring>
#include <vector>

namespace hbrdf::raster {
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

}  // namespace

void check(VkResult r, const char* what) {
    if (r != VK_SUCCESS) throw std::runtime_error(std::string(what) + " failed (VkResult " + std::to_string(r) + ")");
}

int Device::validation_messages() { return g_validation_messages; }

Device::Device(bool validation, VkQueueFlags queue, const char* app_name, bool bc) {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = app_name;
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
    const VkResult created = vkCreateInstance(&ici, nullptr, &instance_);
    if (created == VK_ERROR_INCOMPATIBLE_DRIVER)
        throw std::runtime_error("no Vulkan driver (VK_ERROR_INCOMPATIBLE_DRIVER): install one (Debian: mesa-vulkan-drivers "
                                 "for lavapipe) or check VK_DRIVER_FILES");
    if (created == VK_ERROR_LAYER_NOT_PRESENT)
        throw std::runtime_error("--validation needs the Khronos validation layer (Debian: vulkan-validationlayers)");
    check(created, "vkCreateInstance");
    if (validation) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
        if (!create) throw std::runtime_error("validation requested but VK_EXT_debug_utils is unavailable");
        check(create(instance_, &dbg, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
    }

    uint32_t n = 0;
    vkEnumeratePhysicalDevices(instance_, &n, nullptr);
    if (n == 0) throw std::runtime_error("no Vulkan device (is mesa-vulkan-drivers installed?)");
    std::vector<VkPhysicalDevice> all(n);
    vkEnumeratePhysicalDevices(instance_, &n, all.data());
    physical_ = all[0];
    vkGetPhysicalDeviceProperties(physical_, &props_);
    for (VkPhysicalDevice p : all) {
        VkPhysicalDeviceProperties pp;
        vkGetPhysicalDeviceProperties(p, &pp);
        if (pp.deviceType == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU && props_.deviceType != pp.deviceType) {
            physical_ = p;
            props_ = pp;
        }
    }
    vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);

    uint32_t n_families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &n_families, nullptr);
    std::vector<VkQueueFamilyProperties> families(n_families);
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &n_families, families.data());
    family_ = UINT32_MAX;
    for (uint32_t i = 0; i < n_families && family_ == UINT32_MAX; ++i)
        if ((families[i].queueFlags & queue) == queue) family_ = i;
    if (family_ == UINT32_MAX)
        throw std::runtime_error(std::string(queue & VK_QUEUE_GRAPHICS_BIT ? "no graphics queue on " : "no compute queue on ") +
                                 props_.deviceName);
    timestamp_bits_ = props_.limits.timestampPeriod > 0 ? families[family_].timestampValidBits : 0;

    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qci.queueFamilyIndex = family_;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    // BC images may be created and sampled only with textureCompressionBC enabled (a KTX2 map in a
    // block format); half arithmetic in shaders (SPIR-V Float16: bench/shader_forms.py's packed-half
    // forms) needs shaderFloat16, through VK_KHR_shader_float16_int8 since this instance asks for
    // Vulkan 1.1 (core in 1.2). Buffers stay float32: no 16-bit storage is needed.
    VkPhysicalDeviceFeatures available{};
    vkGetPhysicalDeviceFeatures(physical_, &available);
    VkPhysicalDeviceFeatures enabled{};
    texture_compression_bc_ = bc && available.textureCompressionBC == VK_TRUE;
    enabled.textureCompressionBC = texture_compression_bc_ ? VK_TRUE : VK_FALSE;
    dci.pEnabledFeatures = &enabled;
    uint32_t n_ext = 0;
    vkEnumerateDeviceExtensionProperties(physical_, nullptr, &n_ext, nullptr);
    std::vector<VkExtensionProperties> exts(n_ext);
    vkEnumerateDeviceExtensionProperties(physical_, nullptr, &n_ext, exts.data());
    bool has_f16_ext = false;
    for (const VkExtensionProperties& e : exts)
        has_f16_ext = has_f16_ext || !std::strcmp(e.extensionName, VK_KHR_SHADER_FLOAT16_INT8_EXTENSION_NAME);
    VkPhysicalDeviceShaderFloat16Int8FeaturesKHR f16{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_FLOAT16_INT8_FEATURES_KHR};
    const char* device_extensions[] = {VK_KHR_SHADER_FLOAT16_INT8_EXTENSION_NAME};
    if (has_f16_ext) {
        VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
        features.pNext = &f16;
        vkGetPhysicalDeviceFeatures2(physical_, &features);
        f16.shaderInt8 = VK_FALSE;  // only what the half forms use
        if (f16.shaderFloat16) {
            dci.pNext = &f16;
            dci.enabledExtensionCount = 1;
            dci.ppEnabledExtensionNames = device_extensions;
            shader_float16_ = true;
        }
    }
    check(vkCreateDevice(physical_, &dci, nullptr, &device_), "vkCreateDevice");
    vkGetDeviceQueue(device_, family_, 0, &queue_);
    VkCommandPoolCreateInfo cpci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    cpci.queueFamilyIndex = family_;
    check(vkCreateCommandPool(device_, &cpci, nullptr, &pool_), "vkCreateCommandPool");
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(vkCreateFence(device_, &fci, nullptr, &fence_), "vkCreateFence");
}

Device::~Device() {
    if (device_) {
        vkDeviceWaitIdle(device_);
        vkDestroyFence(device_, fence_, nullptr);
        vkDestroyCommandPool(device_, pool_, nullptr);
        vkDestroyDevice(device_, nullptr);
    }
    if (messenger_) {
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
        if (destroy) destroy(instance_, messenger_, nullptr);
    }
    if (instance_) vkDestroyInstance(instance_, nullptr);
}

VkFormatFeatureFlags Device::format_features(VkFormat format) const {
    VkFormatProperties p{};
    vkGetPhysicalDeviceFormatProperties(physical_, format, &p);
    return p.optimalTilingFeatures;
}

uint32_t Device::memory_type(uint32_t allowed, VkMemoryPropertyFlags want, bool strict) const {
    for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i)
        if ((allowed & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & want) == want) return i;
    for (uint32_t i = 0; i < memory_.memoryTypeCount && !strict; ++i)
        if (allowed & (1u << i)) return i;
    throw std::runtime_error(strict ? "no host-visible coherent memory type" : "no memory type");
}

Buffer Device::make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, VkMemoryPropertyFlags want) const {
    Buffer b;
    b.size = size;
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size;
    bi.usage = usage;
    bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    check(vkCreateBuffer(device_, &bi, nullptr, &b.buffer), "vkCreateBuffer");
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, b.buffer, &req);
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = memory_type(req.memoryTypeBits, want, want & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT);
    check(vkAllocateMemory(device_, &ai, nullptr, &b.memory), "vkAllocateMemory");
    check(vkBindBufferMemory(device_, b.buffer, b.memory, 0), "vkBindBufferMemory");
    return b;
}

Buffer Device::upload(const void* bytes, std::size_t size, VkBufferUsageFlags usage) const {
    const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    Buffer stage = make_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, host);
    void* mapped = nullptr;
    check(vkMapMemory(device_, stage.memory, 0, size, 0, &mapped), "vkMapMemory");
    std::memcpy(mapped, bytes, size);
    vkUnmapMemory(device_, stage.memory);
    Buffer b = make_buffer(size, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    VkCommandBuffer cmd = begin_commands();
    const VkBufferCopy copy{0, 0, size};
    vkCmdCopyBuffer(cmd, stage.buffer, b.buffer, 1, &copy);
    submit_and_wait(cmd);  // the queue's completion makes the copy visible to later submissions
    free_commands(cmd);
    destroy(stage);
    return b;
}

Image Device::make_image(uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage,
                         VkImageAspectFlags aspect, uint32_t levels) const {
    Image im;
    VkImageCreateInfo ici{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    ici.imageType = VK_IMAGE_TYPE_2D;
    ici.format = format;
    ici.extent = {width, height, 1};
    ici.mipLevels = levels;
    ici.arrayLayers = 1;
    ici.samples = VK_SAMPLE_COUNT_1_BIT;
    ici.tiling = VK_IMAGE_TILING_OPTIMAL;
    ici.usage = usage;
    ici.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    check(vkCreateImage(device_, &ici, nullptr, &im.image), "vkCreateImage");
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(device_, im.image, &req);
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, false);
    check(vkAllocateMemory(device_, &ai, nullptr, &im.memory), "vkAllocateMemory");
    check(vkBindImageMemory(device_, im.image, im.memory, 0), "vkBindImageMemory");
    VkImageViewCreateInfo vci{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    vci.image = im.image;
    vci.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vci.format = format;
    vci.subresourceRange = {aspect, 0, levels, 0, 1};
    check(vkCreateImageView(device_, &vci, nullptr, &im.view), "vkCreateImageView");
    return im;
}

void Device::destroy(Buffer& b) const {
    if (b.buffer) vkDestroyBuffer(device_, b.buffer, nullptr);
    if (b.memory) vkFreeMemory(device_, b.memory, nullptr);
    b = Buffer{};
}

void Device::destroy(Image& i) const {
    if (i.view) vkDestroyImageView(device_, i.view, nullptr);
    if (i.image) vkDestroyImage(device_, i.image, nullptr);
    if (i.memory) vkFreeMemory(device_, i.memory, nullptr);
    i = Image{};
}

VkCommandBuffer Device::begin_commands() const {
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool_;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    VkCommandBuffer cmd;
    check(vkAllocateCommandBuffers(device_, &ai, &cmd), "vkAllocateCommandBuffers");
    VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    return cmd;
}

void Device::submit_and_wait(VkCommandBuffer cmd, bool end) const {
    if (end) check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd;
    check(vkQueueSubmit(queue_, 1, &si, fence_), "vkQueueSubmit");
    check(vkWaitForFences(device_, 1, &fence_, VK_TRUE, UINT64_MAX), "vkWaitForFences");
    check(vkResetFences(device_, 1, &fence_), "vkResetFences");
}

void Device::free_commands(VkCommandBuffer cmd) const { vkFreeCommandBuffers(device_, pool_, 1, &cmd); }

}  // namespace hbrdf::raster
