// hbrdf_raster — draws a tracer scene the way an engine does: a headless Vulkan graphics pipeline
// (vertex + fragment SPIR-V given on the command line; the fragment stage includes the generated
// GLSL of the scene's materials, glsl/raster.frag), one draw per object, the scene's point and
// directional lights summed per pixel. NO SHADOWS: every light reaches every surface that faces it
// (the tracer's "shadows": 0). One sample at each pixel centre, no environment light: the picture of
// the tracer's deterministic direct-light mode (max_depth 1, pixel_jitter 0, a black environment).
//
//   hbrdf_raster SCENE.json VERT.spv FRAG.spv --out OUT.exr [--png OUT.png] [--model-material NAME]...
//                [--texture MAP.hbtx|MAP.ktx2]... [--clamp] [--gltf-slots S] [--sphere-segments 512] [--validation] [--repeat R]
//
// The scene is read by the tracer's own loader (hybridbrdf_render). --model-material names, in
// order, the scene materials the fragment shader evaluates as constants of the generated code
// (cases 1, 2, ...); the others draw as f_a with their parameters (case 0). --texture names, in
// binding order (3, 4, ...), the maps of a textured material (textures.hpp): an HBTX file carries
// its addressing, a KTX2 file (uploaded as stored: its chain, its format, BC blocks decoded by the
// texture unit) is sampled with repeat addressing, or clamp to edge with --clamp (the folder's
// "addressing"; hbrdf raster passes it). --gltf-slots: how many
// glTF texture samplers the fragment shader declares after those bindings; the scene's glTF
// textures fill them in slot order (frame_scene.hpp), 1 x 1 white textures the rest (more glTF
// textures than slots is refused). Spheres are tessellated
// (frame_scene.hpp); "sphere_gap" prints how far inside the sphere its flat triangles reach.
// --validation enables the Khronos validation layer: any warning or error fails the run (status 3).
// --repeat R draws R more frames and prints the best time (host clock around submit + wait,
// "best_ms"; where the queue has timestamps, the render pass on the device's clock, "best_gpu_ms";
// and the process's CPU time per frame, "best_cpu_ms": on lavapipe, whose threads are this
// process's, the work a frame costs whatever else the machine runs).
// The SPIR-V is trusted past its header: a driver may crash on a malformed module, so run spirv-val
// first (hbrdf raster does, after glslangValidator).
// Pin lavapipe with VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "device.hpp"
#include "frame_scene.hpp"
#include "hybridbrdf/render/scene_loader.hpp"
#include "pipeline.hpp"
#include "readback.hpp"
#include "textures.hpp"

namespace {

using namespace hbrdf;
using namespace hbrdf::raster;

struct Args {
    std::string scene, vert, frag, out, png;
    std::vector<std::string> model_materials, textures;
    int sphere_segments = 512, repeat = 0, gltf_slots = 0;
    bool validation = false, clamp = false;
};

const char* kUsage =
    "usage: hbrdf_raster SCENE.json VERT.spv FRAG.spv --out OUT.exr [--png OUT.png] [--model-material NAME]... "
    "[--texture MAP.hbtx|MAP.ktx2]... [--clamp] [--gltf-slots S] [--sphere-segments 512] [--validation] [--repeat R]";

int parse_int(const char* flag, const char* text, int lo, int hi) {
    char* end = nullptr;
    const long v = std::strtol(text, &end, 10);
    if (!*text || *end || v < lo || v > hi)
        throw std::invalid_argument(std::string(flag) + ": expected an integer in [" + std::to_string(lo) + ", " +
                                    std::to_string(hi) + "], got '" + text + "'");
    return int(v);
}

Args parse(int argc, char** argv) {
    Args a;
    std::vector<std::string> positional;
    for (int i = 1; i < argc; ++i) {
        const std::string s = argv[i];
        const bool has_value = i + 1 < argc;
        if (s == "--validation") a.validation = true;
        else if (s == "--clamp") a.clamp = true;
        else if (s == "--out" && has_value) a.out = argv[++i];
        else if (s == "--png" && has_value) a.png = argv[++i];
        else if (s == "--model-material" && has_value) a.model_materials.push_back(argv[++i]);
        else if (s == "--texture" && has_value) a.textures.push_back(argv[++i]);
        else if (s == "--sphere-segments" && has_value) a.sphere_segments = parse_int("--sphere-segments", argv[++i], 8, 8192);
        else if (s == "--gltf-slots" && has_value) a.gltf_slots = parse_int("--gltf-slots", argv[++i], 0, 256);
        else if (s == "--repeat" && has_value) a.repeat = parse_int("--repeat", argv[++i], 0, 100000);
        else if (s.rfind("--", 0) == 0) throw std::invalid_argument("unknown or incomplete argument " + s + "\n" + kUsage);
        else positional.push_back(s);
    }
    if (positional.size() != 3 || a.out.empty()) throw std::invalid_argument(kUsage);
    a.scene = positional[0], a.vert = positional[1], a.frag = positional[2];
    return a;
}

std::vector<char> read_spirv(const std::string& path) {
    render::check_input_file(path, "SPIR-V file");
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.eof() && !in) throw render::FileError(path, "cannot read");
    if (bytes.size() < 20 || bytes.size() % 4) throw render::FileError(path, "not SPIR-V: its size is not a multiple of 4 of at least 20 bytes");
    uint32_t magic;
    std::memcpy(&magic, bytes.data(), 4);
    if (magic != 0x07230203u) throw render::FileError(path, "not SPIR-V: no SPIR-V magic number");
    return bytes;
}

// Records the frame: the render pass and one draw per object, between two timestamps.
void record_frame(VkCommandBuffer cmd, const FramePipeline& pipe, const FrameScene& fs, VkBuffer vertices,
                  VkBuffer indices, VkQueryPool queries) {
    if (queries) {
        vkCmdResetQueryPool(cmd, queries, 0, 2);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, 0);
    }
    pipe.begin(cmd);
    const VkDeviceSize zero = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &vertices, &zero);
    vkCmdBindIndexBuffer(cmd, indices, 0, VK_INDEX_TYPE_UINT32);
    for (const Draw& d : fs.draws) {
        const DrawConstants pc{d.material};
        vkCmdPushConstants(cmd, pipe.layout(), VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof pc, &pc);
        vkCmdDrawIndexed(cmd, d.index_count, 1, d.first_index, d.vertex_offset, 0);
    }
    pipe.end(cmd);
    if (queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 1);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
}

// The CPU time of this process and all its threads, in ms.
double process_cpu_ms() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

// The uniform block at binding 0: the camera. Built as hbrdf_raster_bench_uniform (EXCLUDE_FROM_ALL,
// bench/raster_anatomy.py's uniform weight forms, docs/RASTER.md "The floor under lavapipe") the
// float32 values of the file HBRDF_BENCH_UNIFORM names follow it, which the shader reads as more of
// the block (the network's weights at constant offsets, against literals; Mesa 22.3's llvmpipe reads
// each as a bounds-tested 8-lane gather, not a load and a broadcast).
std::vector<float> camera_block(const FrameScene& fs) {
    std::vector<float> block(std::begin(fs.camera), std::end(fs.camera));
#ifdef HBRDF_RASTER_BENCH_UNIFORM
    if (const char* path = std::getenv("HBRDF_BENCH_UNIFORM")) {
        std::ifstream in(path, std::ios::binary);
        const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        if (!in.good() && !in.eof()) throw std::runtime_error(std::string(path) + ": cannot be read");
        block.resize(block.size() + bytes.size() / 4);
        std::memcpy(block.data() + std::size(fs.camera), bytes.data(), bytes.size() / 4 * 4);
    }
#endif
    return block;
}

int run(int argc, char** argv) {
    const Args a = parse(argc, argv);
    const std::vector<char> vert = read_spirv(a.vert), frag = read_spirv(a.frag);
    render::check_output_path(a.out);
    if (!a.png.empty()) render::check_output_path(a.png);
    const render::Scene scene = render::load_scene(a.scene);
    const FrameScene fs = build_frame_scene(scene, a.model_materials, a.sphere_segments);
    if (fs.indices.empty()) throw std::invalid_argument(a.scene + ": nothing to draw");
    if (fs.gltf_textures.size() > std::size_t(a.gltf_slots))
        throw std::invalid_argument(a.scene + ": its glTF materials read " + std::to_string(fs.gltf_textures.size()) +
                                    " textures; the fragment shader declares " + std::to_string(a.gltf_slots) + " (--gltf-slots)");
    const auto width = uint32_t(scene.camera.width()), height = uint32_t(scene.camera.height());

    Device device(a.validation);
    Buffer vertices = device.upload(fs.vertices.data(), fs.vertices.size() * sizeof(Vertex), VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
    Buffer indices = device.upload(fs.indices.data(), fs.indices.size() * 4, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
    const std::vector<float> uniform_block = camera_block(fs);
    Buffer camera = device.upload(uniform_block.data(), uniform_block.size() * 4, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
    Buffer materials = device.upload(fs.materials.data(), fs.materials.size() * sizeof(GpuMaterial),
                                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    Buffer lights = device.upload(fs.lights.data(), fs.lights.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    int status = 0;
    {
        std::vector<Texture> textures;
        for (const std::string& path : a.textures) textures.push_back(load_texture(device, path, Sampling{a.clamp, false}));
        for (const render::GltfTexture& t : fs.gltf_textures) textures.push_back(upload_gltf_texture(device, t));
        for (std::size_t k = fs.gltf_textures.size(); k < std::size_t(a.gltf_slots); ++k) textures.push_back(blank_texture(device));
        FramePipeline pipe(device, width, height, vert, frag, uint32_t(textures.size()));
        pipe.bind_buffers(camera, materials, lights, textures);
        if (device.validation_messages()) {  // a pipeline the layer refused may crash a driver when drawn
            std::fprintf(stderr, "hbrdf_raster: %d validation message(s) before drawing\n", device.validation_messages());
            for (Texture& t : textures) destroy(device, t);
            for (Buffer* b : {&vertices, &indices, &camera, &materials, &lights}) device.destroy(*b);
            return 3;
        }
        VkQueryPool queries = VK_NULL_HANDLE;
        if (device.timestamp_bits()) {
            VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
            qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
            qpi.queryCount = 2;
            check(vkCreateQueryPool(device.handle(), &qpi, nullptr, &queries), "vkCreateQueryPool");
        }
        VkCommandBuffer cmd = device.begin_commands();
        record_frame(cmd, pipe, fs, vertices.buffer, indices.buffer, queries);
        const uint64_t mask = device.timestamp_bits() < 64 ? (uint64_t(1) << device.timestamp_bits()) - 1 : ~uint64_t(0);
        double best_ms = 1e30, best_cpu_ms = 1e30;
        std::vector<double> gpu_ms;
        for (int r = 0; r <= a.repeat; ++r) {
            const auto t0 = std::chrono::steady_clock::now();
            const double cpu0 = process_cpu_ms();
            device.submit_and_wait(cmd, false);
            const double cpu_ms = process_cpu_ms() - cpu0;
            const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
            if (r == 0 && a.repeat > 0) continue;  // the first frame warms up when repeating
            best_ms = std::min(best_ms, ms);
            best_cpu_ms = std::min(best_cpu_ms, cpu_ms);
            uint64_t ticks[2];
            if (queries && vkGetQueryPoolResults(device.handle(), queries, 0, 2, sizeof ticks, ticks, sizeof ticks[0],
                                                 VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS)
                gpu_ms.push_back(double((ticks[1] - ticks[0]) & mask) * device.properties().limits.timestampPeriod * 1e-6);
        }
        device.free_commands(cmd);
        const render::Image image = read_color(device, pipe.color_image(), width, height);
        if (queries) vkDestroyQueryPool(device.handle(), queries, nullptr);
        for (Texture& t : textures) destroy(device, t);
        std::printf("device %s\nsize %u %u\ntriangles %zu\ndraws %zu\nsphere_gap %.3g\nbest_ms %.4f\nbest_cpu_ms %.4f\n",
                    device.properties().deviceName, width, height, fs.indices.size() / 3, fs.draws.size(),
                    fs.max_sphere_gap, best_ms, best_cpu_ms);
        if (!gpu_ms.empty()) {
            std::sort(gpu_ms.begin(), gpu_ms.end());
            std::printf("best_gpu_ms %.4f\nmedian_gpu_ms %.4f\n", gpu_ms.front(), gpu_ms[gpu_ms.size() / 2]);
        }
        if (device.validation_messages()) {
            std::fprintf(stderr, "hbrdf_raster: %d validation message(s)\n", device.validation_messages());
            status = 3;
        } else {  // both outputs staged, then both committed: a failure leaves neither half-written
            render::StagedFile exr = render::stage_exr(image, a.out);
            if (!a.png.empty()) {
                render::StagedFile png = render::stage_png(image, a.png);
                exr.commit();
                png.commit();
            } else {
                exr.commit();
            }
        }
    }
    for (Buffer* b : {&vertices, &indices, &camera, &materials, &lights}) device.destroy(*b);
    return status;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "hbrdf_raster: %s\n", hbrdf::one_line_text(e.what()).c_str());
        return 1;
    }
}
