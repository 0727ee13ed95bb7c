// Hostile input and interruption (docs/RENDERING.md, "Limits and validation",
// "Cancellation"): cancellation stops render() and load_scene() promptly; sizes
// beyond the limits, negative or overflowing radiances and malformed meshes are
// one-line errors naming the key before anything large is allocated; outputs
// are checked before a render and replaced only when it completes.
#include <doctest/doctest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "hybridbrdf/render/render.hpp"

using namespace hbrdf::render;

namespace {

const std::string kCam = R"("camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 16, "height": 16})";
const std::string kSphere = R"("objects": [{"type": "sphere", "material": {"type": "analytic"}}])";

// The FileError message of loading `text` ("no error" when it loads).
std::string load_error(const std::string& text, const std::string& base_dir = ".") {
    try {
        load_scene_json(text, base_dir, "bad.json");
    } catch (const FileError& e) {
        return e.what();
    }
    return "no error";
}

// A scene with `environment` under the default camera and a sphere.
std::string with_environment(const std::string& environment) {
    return "{" + kCam + R"(, "environment": )" + environment + ", " + kSphere + "}";
}

// An environment and the error of loading it under the default camera and a sphere.
struct EnvironmentError {
    const char* environment;
    const char* error;
};

void check_environment_errors(std::initializer_list<EnvironmentError> cases) {
    for (const EnvironmentError& c : cases) {
        CAPTURE(c.environment);
        CHECK(load_error(with_environment(c.environment)) == c.error);
    }
}

std::string read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_file(const std::string& path, const std::string& bytes) { std::ofstream(path, std::ios::binary) << bytes; }

bool exists(const std::string& path) { return std::ifstream(path).good(); }

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

TEST_CASE("cancellation: render() throws Cancelled within a wave of the flag, even inside one tile") {
    // One 16x16 tile of 2^24 samples per pixel: hours of work in 16-sample waves,
    // so only the check between waves can stop it in time.
    const Scene scene = load_scene_json("{" + kCam + ", " + kSphere + "}", ".", "<test>");
    RenderOptions o;
    o.spp = 1 << 24;
    o.quiet = true;
    std::atomic<bool> cancel{true};
    o.cancel = &cancel;
    for (int threads : {1, 2}) {
        o.threads = threads;
        cancel = true;
        CHECK_THROWS_AS(render(scene, o), Cancelled);  // set before: returns at once
        cancel = false;
        std::thread setter([&] {
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
            cancel = true;
        });
        const auto t0 = std::chrono::steady_clock::now();
        CHECK_THROWS_AS(render(scene, o), Cancelled);
        const double elapsed = seconds_since(t0);
        setter.join();
        CHECK(elapsed < 2.0);
    }
}

TEST_CASE("cancellation: load_scene_json() checks the flag between the parts of a scene") {
    std::atomic<bool> cancel{true};
    SceneLoadOptions options;
    options.cancel = &cancel;
    CHECK_THROWS_AS(load_scene_json("{" + kCam + ", " + kSphere + "}", ".", "<test>", options), Cancelled);
    cancel = false;
    CHECK_NOTHROW(load_scene_json("{" + kCam + ", " + kSphere + "}", ".", "<test>", options));
}

TEST_CASE("limits: film and environment sizes are checked before anything is allocated") {
    CHECK(format_bytes(1.2e11) == "120 GB");
    CHECK(format_bytes(3.2e9) == "3.2 GB");
    CHECK(format_bytes(999) == "999 bytes");
    const Vec3f eye(0, 0, 3), at(0, 0, 0), up(0, 1, 0);
    CHECK_NOTHROW(PinholeCamera(eye, at, up, 40, 16384, 8192));  // the limit itself: 2^27 pixels
    CHECK_THROWS_AS(PinholeCamera(eye, at, up, 40, 16384, 8193), std::invalid_argument);
    const std::string cam = R"("camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 100000, "height": 100000})";
    CHECK(load_error("{" + cam + ", " + kSphere + "}") ==
          "bad.json: camera: width x height = 100000 x 100000 = 10000000000 pixels need ~120 GB of film "
          "(limit 134217728 pixels, e.g. 16384 x 8192)");
    CHECK(load_error(with_environment(R"({"type": "sky", "resolution": [100000, 50000]})")) ==
          "bad.json: environment.resolution: 100000 x 50000 = 5000000000 pixels need ~140 GB with its sampling "
          "tables (limit 134217728 pixels, e.g. 16384 x 8192)");
    check_environment_errors({
        // Resolutions are integers, bounded before the conversion (a float 1e10 was cast to int: undefined).
        {R"({"type": "sky", "resolution": [1e10, 64]})",
         "bad.json: environment.resolution[0]: expected an integer, got 10000000000.0"},
        {R"({"type": "sky", "resolution": [3000000000, 64]})",
         "bad.json: environment.resolution[0]: must be <= 2147483647, got 3000000000"},
        {R"({"type": "sky", "resolution": [2, 64]})",
         "bad.json: environment.resolution: must be at least 4 x 2, got 2 x 64"},
    });
    SkyParams sky;
    sky.width = 100000;
    sky.height = 50000;
    CHECK_THROWS_WITH_AS(make_sky_image(sky), doctest::Contains("resolution: 100000 x 50000"), std::invalid_argument);
    CHECK(load_error("{" + kCam + R"(, "threads": 1025, )" + kSphere + "}") == "bad.json: threads: must be <= 1024, got 1025");
}

TEST_CASE("limits: an image header that declares too many pixels is refused before decoding") {
    Image img(4, 2);
    const std::string path = "hbrdf_hostile_forged.exr";
    write_exr(img, path);
    std::string bytes = read_file(path);
    // Forge the header: a 20000 x 10000 data window over four pixels of data.
    for (const std::string& attr : {std::string("dataWindow\0box2i\0", 17), std::string("displayWindow\0box2i\0", 20)}) {
        const auto at = bytes.find(attr);
        REQUIRE(at != std::string::npos);
        const int box[4] = {0, 0, 19999, 9999};
        std::memcpy(&bytes[at + attr.size() + 4], box, sizeof box);
    }
    write_file(path, bytes);
    CHECK_THROWS_WITH_AS(read_image(path), doctest::Contains("20000 x 10000 = 200000000 pixels need ~5.6 GB of memory"),
                         FileError);
    std::remove(path.c_str());
}

TEST_CASE("validation: radiances, scales and albedos are finite and >= 0, named by their key") {
    check_environment_errors({
        {R"({"type": "sky", "scale": -1})", "bad.json: environment.scale: must be >= 0, got -1"},
        {R"({"type": "constant", "radiance": [1, -2, 1]})", "bad.json: environment.radiance[1]: must be >= 0, got -2"},
        {R"({"type": "constant", "radiance": -1})", "bad.json: environment.radiance: must be >= 0, got -1"},
        {R"({"type": "sky", "ground_albedo": -0.5})", "bad.json: environment.ground_albedo: must be >= 0, got -0.5"},
        {R"({"type": "sky", "sun_irradiance": [1, -1, 1]})",
         "bad.json: environment.sun_irradiance[1]: must be >= 0, got -1"},
        {R"({"type": "sky", "sky_intensity": -3})", "bad.json: environment.sky_intensity: must be >= 0, got -3"},
        {R"({"type": "sky", "turbidity": 12})", "bad.json: environment.turbidity: must be in [1, 10], got 12"},
        // Beyond float: 1e300 would become inf after the conversion.
        {R"({"type": "sky", "scale": 1e300})", "bad.json: environment.scale: must be within +-3.40282e+38, got 1e+300"},
        // Finite factors whose product is not.
        {R"({"type": "constant", "radiance": 1e30, "scale": 1e30})",
         "bad.json: environment: scale: 1e+30 x the brightest texel (1e+30) overflows float"},
    });
    // A sun too small for float: its radiance (irradiance / solid angle) would be infinite.
    CHECK(load_error(with_environment(R"({"type": "sky", "sun_size_deg": 1e-30})"))
              .rfind("bad.json: environment.sun_size_deg: is too small for sun_irradiance", 0) == 0);
    CHECK_THROWS_AS(EnvironmentLight(Image(8, 4), -1.0f), std::invalid_argument);
}

TEST_CASE("validation: meshes with out-of-range indices or non-finite vertices are errors, not crashes") {
    // Index 7 of 3 vertices crashed assimp's post-processing before ValidateDataStructure ran first.
    write_file("hbrdf_hostile_badidx.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                           "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                           "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    write_file("hbrdf_hostile_nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    write_file("hbrdf_hostile_big.obj", "v 0 0 0\nv 1e10 0 0\nv 0 1 0\nf 1 2 3\n");
    auto mesh = [](const std::string& file, const std::string& extra = "") {
        return "{" + kCam + R"(, "objects": [{"type": "mesh", "file": ")" + file + "\"" + extra +
               R"(, "material": {"type": "analytic"}}]})";
    };
    CHECK(load_error(mesh("hbrdf_hostile_badidx.ply")).find("is out of range") != std::string::npos);
    CHECK(load_error(mesh("hbrdf_hostile_nan.obj")) == "bad.json: objects[0].file: ./hbrdf_hostile_nan.obj: vertex 1 is not finite");
    CHECK(load_error(mesh("hbrdf_hostile_big.obj", R"(, "transform": {"scale": 1e30})")) ==
          "bad.json: objects[0].transform: moves vertex 1 beyond the float range");
    for (const char* f : {"hbrdf_hostile_badidx.ply", "hbrdf_hostile_nan.obj", "hbrdf_hostile_big.obj"}) std::remove(f);

    Scene scene;
    TriangleMesh m;
    m.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0)};
    m.indices = {0, 1, 7};
    CHECK_THROWS_WITH_AS(scene.add_mesh(m, 0), "triangle 0 refers to vertex 7, but the mesh has 3 vertices",
                         std::invalid_argument);
    CHECK(load_error("{" + kCam + R"(, "objects": [{"type": "sphere", "center": [3e38, 0, 0], "radius": 1e38,
                                                    "material": {"type": "analytic"}}]})") ==
          "bad.json: objects[0]: the sphere's bounds (center +- radius) overflow float");
}

TEST_CASE("outputs: checked before a render, replaced only by a commit") {
    CHECK_THROWS_WITH_AS(check_output_path("."), ".: is a folder, expected a file name", FileError);
    CHECK_THROWS_WITH_AS(check_output_path("/nonexistent-dir/x.exr"),
                         "/nonexistent-dir/x.exr: cannot create files in /nonexistent-dir (No such file or directory)",
                         FileError);
    const std::string path = "hbrdf_hostile_out.exr";
    CHECK_NOTHROW(check_output_path(path));
    CHECK(!exists(path));  // the probe leaves nothing behind
    write_file(path, "previous");
    {
        const StagedFile staged = stage_exr(Image(2, 2), path);
        CHECK(exists(staged.temp_path()));
        CHECK(read_file(path) == "previous");
    }  // not committed (a cancelled render): the temporary goes, the old file stays
    CHECK(read_file(path) == "previous");
    CHECK(!exists(path + ".tmp" + std::to_string(::getpid())));
    StagedFile staged = stage_exr(Image(2, 2), path);
    staged.commit();
    CHECK(read_image(path).width == 2);
    std::remove(path.c_str());
}

TEST_CASE("validation: an environment too bright for float32 sums, and a film that is not finite, are errors") {
    check_environment_errors({
        // 1e30 x 1: finite, but 16 samples of it through a path's throughput can reach +Inf.
        {R"({"type": "constant", "radiance": 1e21})",
         "bad.json: environment: the brightest texel x scale is 1e+21, above the limit 1e+20 (a pixel's samples "
         "would overflow float32)"},
        {R"({"type": "constant", "radiance": 1e20})", "no error"},
    });
    // The last guard, whatever the light: render() refuses an image holding Inf or NaN.
    Scene scene = load_scene_json(with_environment(R"({"type": "constant", "radiance": 2})"), ".", "ok.json");
    Image img(4, 2);
    CHECK(film_problem(img, scene).empty());
    img.at(3, 1)[2] = std::numeric_limits<float>::infinity();
    img.at(1, 1)[0] = std::numeric_limits<float>::quiet_NaN();
    CHECK(film_problem(img, scene) ==
          "the rendered image holds 2 values that are not finite (the first at pixel (1, 1)): the light along its "
          "paths overflows float32 (the environment's brightest radiance is 2)");
}

TEST_CASE("special files: environment maps and meshes that are FIFOs or devices are refused before opening") {
    const std::string fifo = "hbrdf_hostile_fifo.hdr";
    std::remove(fifo.c_str());
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    const auto t0 = std::chrono::steady_clock::now();
    CHECK_THROWS_WITH_AS(read_image(fifo), "hbrdf_hostile_fifo.hdr: is a FIFO, not a regular file", FileError);
    CHECK_THROWS_WITH_AS(read_image("/dev/zero"), "/dev/zero: is a character device, not a regular file", FileError);
    CHECK(load_error("{" + kCam + R"(, "objects": [{"type": "mesh", "file": "hbrdf_hostile_fifo.hdr", "material": {"type": "analytic"}}]})")
              .find("hbrdf_hostile_fifo.hdr: is a FIFO, not a regular file") != std::string::npos);
    CHECK(seconds_since(t0) < 10.0);  // an open() of the FIFO would have blocked for ever
    std::remove(fifo.c_str());
}

TEST_CASE("limits: a Radiance HDR file is refused when its pixel data end early") {
    const std::string path = "hbrdf_hostile_truncated.hdr";
    const std::string header = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n";
    write_file(path, header + "-Y 4096 +X 32768\n");  // 4096 x 32768 declared, no pixel present
    CHECK_THROWS_WITH_AS(read_image(path), "hbrdf_hostile_truncated.hdr: truncated: scanline 1 of 4096", FileError);
    std::string flat = header + "-Y 4 +X 4\n";
    for (int i = 0; i < 16; ++i) flat += std::string("\x80\x80\x80\x81", 4);
    write_file(path, flat);
    CHECK(read_image(path).rgb[0] == 1.0f);
    write_file(path, flat.substr(0, flat.size() - 20));
    CHECK_THROWS_WITH_AS(read_image(path), "hbrdf_hostile_truncated.hdr: truncated: scanline 3 of 4", FileError);
    std::remove(path.c_str());
}

TEST_CASE("validation: environment texels that are not finite or negative are refused, naming the texel") {
    const float inf = std::numeric_limits<float>::infinity();
    const std::string rule = "; an environment map's texels must be finite radiances >= 0 (docs/RENDERING.md, \"Environments\")";
    Image img(4, 2);
    std::fill(img.rgb.begin(), img.rgb.end(), 1.0f);
    img.at(3, 1)[1] = inf;  // a clipped sun: it used to be zeroed, and the sun was gone
    auto light = [](const Image& image) { return EnvironmentLight(image); };
    CHECK_THROWS_WITH_AS(light(img), ("texel (3, 1) G = inf is not finite" + rule).c_str(), std::invalid_argument);
    img.at(3, 1)[1] = 1.0f;
    img.at(0, 1)[2] = -0.5f;
    CHECK_THROWS_WITH_AS(light(img), ("texel (0, 1) B = -0.5 is negative" + rule).c_str(), std::invalid_argument);
    img.at(0, 1)[2] = 0.0f;  // black is a radiance
    CHECK_NOTHROW(light(img));
}

TEST_CASE("limits: geometry and cameras beyond what float32 places at the camera's scale are refused") {
    const std::string why = "; float32 places points that far out too coarsely (docs/RENDERING.md, \"Limits\")";
    auto sphere = [](const char* center, const char* radius) {
        return "{" + kCam + R"(, "objects": [{"type": "sphere", "center": )" + center + R"(, "radius": )" + radius +
               R"(, "material": {"type": "analytic"}}]})";
    };
    // kCam is 3 from its look_at point: 5e4 x 3 = 150000.
    CHECK(load_error(sphere("[0, 0, 0]", "1.5e5")) == "no error");
    CHECK(load_error(sphere("[0, 0, 0]", "1e6")) ==
          "bad.json: objects[0]: the sphere (center (0, 0, 0), radius 1e+06) has a coordinate of magnitude 1e+06, above "
          "the limit 150000 = 50000 x the camera's distance to its look_at point (3)" + why);
    CHECK(load_error(R"({"camera": {"position": [0, 0, 1e13], "look_at": [0, 0, 0]}, )" + kSphere + "}") ==
          "bad.json: camera: position has a coordinate of magnitude 1e+13, above the limit 1e+12 for any coordinate "
          "(docs/RENDERING.md, \"Limits\")");
    CHECK(load_error(R"({"camera": {"position": [0, 0, 1600], "look_at": [0, 0, 1597]}, )" + kSphere + "}") ==
          "bad.json: camera: position has a coordinate of magnitude 1600, above the limit 1500 = 500 x its distance to "
          "look_at (3): rays that far out start too far from their surfaces; move the scene's origin near the camera, "
          "or look_at onto the subject (docs/RENDERING.md, \"Limits\")");
    Scene scene;  // a default camera frames at distance 1
    TriangleMesh m;
    m.positions = {Vec3f(0, 0, 0), Vec3f(6e4f, 0, 0), Vec3f(0, 1, 0)};
    m.indices = {0, 1, 2};
    CHECK_THROWS_WITH_AS(scene.add_mesh(m, 0),
                         ("vertex 1 (60000, 0, 0) has a coordinate of magnitude 60000, above the limit 50000 = 50000 x "
                          "the camera's distance to its look_at point (1)" + why).c_str(),
                         std::invalid_argument);
}

TEST_CASE("outputs: a stale temporary (even a symlink) is replaced, not followed; a replaced output keeps its mode") {
    const std::string path = "hbrdf_hostile_mode.exr", victim = "hbrdf_hostile_victim";
    const std::string tmp = path + ".tmp" + std::to_string(::getpid());
    write_file(victim, "untouched");
    REQUIRE(::symlink(victim.c_str(), tmp.c_str()) == 0);
    write_file(path, "previous");
    REQUIRE(::chmod(path.c_str(), 0640) == 0);
    write_exr(Image(2, 2), path);
    CHECK(read_file(victim) == "untouched");
    CHECK(read_image(path).width == 2);
    struct stat st {};
    REQUIRE(::stat(path.c_str(), &st) == 0);
    CHECK((st.st_mode & 07777) == 0640);
    CHECK(!exists(tmp));
    for (const std::string& f : {path, victim}) std::remove(f.c_str());
}
