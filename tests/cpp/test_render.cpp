// Tests of the reference path tracer (docs/RENDERING.md). Independent
// references: the white furnace (a closed-form answer), the env-map pdf
// integrated by quadrature and checked against sample histograms, agreement
// between estimators that share nothing but the scene, and bit-exact
// determinism across thread counts.
#include <doctest/doctest.h>

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "hybridbrdf/render/render.hpp"


using namespace hbrdf::render;
using hbrdf::Vec2;
using hbrdf::dot;

namespace {

const std::string kSourceDir = HBRDF_SOURCE_DIR;

// A sphere of radius 1 at the origin, seen whole by a 24x24 camera; `extra`
// adds top-level keys, `more_objects` objects (a leading comma each).
std::string sphere_scene(const std::string& material, const std::string& environment, const std::string& extra = "",
                         const std::string& more_objects = "") {
    return R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov_deg": 32, "width": 24, "height": 24},
              "environment": )" + environment + R"(,
              "materials": {"m": )" + material + R"(},
              "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"})" +
           more_objects + "]" + extra + "}";
}

// A floor under the sphere, so that paths bounce more than once.
const std::string kFloor = R"(, {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 8, "material": "m"})";

Scene load(const std::string& text) { return load_scene_json(text, kSourceDir, "<test>"); }

double image_mean(const Image& img) {
    double s = 0;
    for (float v : img.rgb) s += v;
    return s / double(img.rgb.size());
}

// Mean and standard error of the image mean over `k` independent seeds.
std::pair<double, double> mean_and_error(const Scene& scene, RenderOptions o, int k) {
    std::vector<double> means;
    for (int i = 0; i < k; ++i) {
        o.seed = 1000 + std::uint64_t(i);
        means.push_back(image_mean(render(scene, o)));
    }
    double m = 0, v = 0;
    for (double x : means) m += x;
    m /= k;
    for (double x : means) v += (x - m) * (x - m);
    v /= (k - 1);
    return {m, std::sqrt(v / k)};
}

RenderOptions quick(int spp, int max_depth = 4) {
    RenderOptions o;
    o.spp = spp;
    o.max_depth = max_depth;
    o.quiet = true;
    o.threads = 2;
    return o;
}

}  // namespace

TEST_CASE("Distribution2D: pdf integrates to 1 and matches sampled frequencies") {
    const int w = 7, h = 5;
    std::vector<float> weights(w * h);
    for (int i = 0; i < w * h; ++i) weights[std::size_t(i)] = float((i * 37) % 11);  // includes zeros
    const Distribution2D d(weights, w, h);
    double integral = 0, total_w = 0;
    for (float x : weights) total_w += x;
    std::vector<double> counts(std::size_t(w * h), 0.0);
    const int n = 200000;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) integral += d.pdf({(x + 0.5f) / w, (y + 0.5f) / h}) / double(w * h);
    CHECK(integral == doctest::Approx(1.0).epsilon(1e-5));
    for (int i = 0; i < n; ++i) {
        float pdf;
        const Vec2<float> uv = d.sample({random_float(1, 0, i, 0), random_float(1, 0, i, 1)}, &pdf);
        CHECK(pdf == doctest::Approx(d.pdf(uv)).epsilon(1e-5));
        counts[std::size_t(int(uv.y * h) * w + int(uv.x * w))] += 1;
    }
    for (int i = 0; i < w * h; ++i) {
        const double expected = n * weights[std::size_t(i)] / total_w;
        if (expected == 0) CHECK(counts[std::size_t(i)] == 0);
        else CHECK(std::fabs(counts[std::size_t(i)] - expected) < 5 * std::sqrt(expected) + 1);
    }
}

TEST_CASE("environment light: pdf integrates to 1 over the sphere and matches a sample histogram") {
    SkyParams sky;
    sky.width = 64;
    sky.height = 32;
    sky.sun_size_deg = 8;  // a few texels, so the test resolves it
    // Rotated by 45 degrees = 8 texels, so that the quadrature grid below
    // (16 x 16 points per texel) never straddles a texel edge.
    const EnvironmentLight env(make_sky_image(sky), 1.0f, 45.0f);
    // Midpoint quadrature in (theta, phi), d omega = sin(theta) d theta d phi:
    // the sin(theta) cancels the 1/sin(theta) of the equirect density, so the
    // integrand is bounded (a grid in cos(theta) would sample a singularity).
    const int nt = 32 * 16, np = 64 * 16;
    auto dir = [](double th, double ph) {
        return Vec3f(float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph)));
    };
    double integral = 0;
    for (int i = 0; i < nt; ++i)
        for (int j = 0; j < np; ++j) {
            const double th = M_PI * (i + 0.5) / nt, ph = 2 * M_PI * (j + 0.5) / np;
            integral += env.pdf(dir(th, ph)) * std::sin(th) * (M_PI / nt) * (2 * M_PI / np);
        }
    CHECK(integral == doctest::Approx(1.0).epsilon(2e-3));

    // Binned test: 8 x 4 bins in (phi, cos theta) of the world direction;
    // expected counts from the quadrature of pdf over each bin.
    const int bp = 8, bt = 4, n = 400000;
    std::vector<double> expected(bp * bt, 0.0), observed(bp * bt, 0.0);
    for (int i = 0; i < nt; ++i)
        for (int j = 0; j < np; ++j) {
            const double th = M_PI * (i + 0.5) / nt, ph = 2 * M_PI * (j + 0.5) / np;
            expected[std::size_t((i * bt / nt) * bp + j * bp / np)] +=
                n * env.pdf(dir(th, ph)) * std::sin(th) * (M_PI / nt) * (2 * M_PI / np);
        }
    for (int k = 0; k < n; ++k) {
        const LightSample s = env.sample({random_float(7, 0, k, 0), random_float(7, 0, k, 1)});
        REQUIRE(s.pdf > 0);
        CHECK(std::fabs(dot(s.wi, s.wi) - 1.0f) < 1e-4f);
        CHECK(s.pdf == doctest::Approx(env.pdf(s.wi)).epsilon(1e-3));
        double ph = std::atan2(double(s.wi.z), double(s.wi.x));
        if (ph < 0) ph += 2 * M_PI;
        const int i = std::min(bt - 1, int(std::acos(std::clamp(double(s.wi.y), -1.0, 1.0)) / M_PI * bt)), j = std::min(bp - 1, int(ph / (2 * M_PI) * bp));
        observed[std::size_t(i * bp + j)] += 1;
    }
    double chi2 = 0;
    for (int b = 0; b < bp * bt; ++b)
        if (expected[std::size_t(b)] > 5) chi2 += (observed[std::size_t(b)] - expected[std::size_t(b)]) * (observed[std::size_t(b)] - expected[std::size_t(b)]) / expected[std::size_t(b)];
    // 31 degrees of freedom: the 1e-4 quantile is about 70. The quadrature
    // error of `expected` (5e-3 relative) adds ~ (5e-3)^2 n = 10.
    CHECK(chi2 < 80);
}

TEST_CASE("procedural sky: the sun disk delivers the irradiance it was given") {
    SkyParams sky;
    sky.sky_intensity = 0;  // sun only
    sky.sun_irradiance = Vec3f(10.0f);
    const Image img = make_sky_image(sky);
    // Irradiance on a surface facing the sun: integral of L cos over texels.
    const EnvironmentLight env(img);
    const Vec3f sun = sky.sun_direction();
    double E = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const float L = img.at(x, y)[0];
            if (L == 0) continue;
            const Vec3f d = env.uv_to_direction({(x + 0.5f) / img.width, (y + 0.5f) / img.height});
            const double omega = 2 * M_PI * M_PI * std::sin(M_PI * (y + 0.5) / img.height) / (img.width * img.height);
            E += L * std::max(0.0f, dot(d, sun)) * omega;
        }
    CHECK(E == doctest::Approx(10.0).epsilon(0.01));
}

TEST_CASE("white furnace: a Lambert kd=1 sphere under a constant environment is invisible") {
    const Scene scene = load(sphere_scene(R"({"type": "analytic", "kd": 1, "eta": 1, "alpha": 0.5})",
                                          R"({"type": "constant", "radiance": [1, 1, 1]})", R"(, "sampler": "cosine")"));
    for (bool nee : {true, false}) {
        RenderOptions o = quick(64, 3);
        o.nee = nee;
        const Image img = render(scene, o);
        double worst = 0;
        for (float v : img.rgb) worst = std::max(worst, std::fabs(double(v) - 1.0));
        CAPTURE(nee);
        CAPTURE(worst);
        // Without NEE every sample is exactly 1 (cosine-sampled Lambert, kd = 1:
        // f cos / pdf = 1, times L = 1): only rounding remains. With NEE the MIS
        // combination is 1 in expectation only.
        if (!nee) CHECK(worst < 1e-5);
        CHECK(image_mean(img) == doctest::Approx(1.0).epsilon(5e-3));
    }
}

TEST_CASE("furnace with albedo: a convex Lambert sphere under L reflects L * kd") {
    const Scene scene = load(sphere_scene(R"({"type": "analytic", "kd": [0.25, 0.5, 0.75], "eta": 1})",
                                          R"({"type": "constant", "radiance": 2})"));
    RenderOptions o = quick(32, 2);
    o.tile_size = 8;
    const Image img = render(scene, o);
    // Pixels that see the sphere (the centre 6x6) are 2 * kd in expectation;
    // their mean over 36 x 32 samples has a standard error of about 1%.
    double m[3] = {0, 0, 0};
    for (int y = 9; y < 15; ++y)
        for (int x = 9; x < 15; ++x)
            for (int c = 0; c < 3; ++c) m[c] += img.at(x, y)[c] / 36.0;
    CHECK(m[0] == doctest::Approx(0.5).epsilon(0.04));
    CHECK(m[1] == doctest::Approx(1.0).epsilon(0.04));
    CHECK(m[2] == doctest::Approx(1.5).epsilon(0.04));
    CHECK(img.at(0, 0)[1] == doctest::Approx(2.0).epsilon(1e-6));
}

TEST_CASE("every sampler and NEE on/off converge to the same image mean") {
    const std::string mat = R"({"type": "analytic", "kd": [0.3, 0.2, 0.1], "eta": [1.5, 1.6, 1.7], "alpha": [0.15, 0.3]})";
    const std::string env = R"({"type": "sky", "resolution": [128, 64], "sun_size_deg": 6, "sun_irradiance": 5})";
    std::vector<std::pair<std::string, std::pair<double, double>>> results;
    for (const char* sampler : {"cosine", "ggx", "mis", "tabulated"}) {
        const Scene scene = load(sphere_scene(mat, env, std::string(R"(, "sampler": ")") + sampler + R"(", "tabulated_resolution_deg": 5)", kFloor));
        results.push_back({sampler, mean_and_error(scene, quick(16, 3), 4)});
    }
    {
        const Scene scene = load(sphere_scene(mat, env, R"(, "sampler": "mis")", kFloor));
        RenderOptions o = quick(16, 3);
        o.nee = false;
        results.push_back({"mis, no NEE", mean_and_error(scene, o, 4)});
    }
    const auto& ref = results[2].second;  // mis with NEE
    for (const auto& r : results) {
        CAPTURE(r.first);
        CAPTURE(r.second.first);
        CAPTURE(r.second.second);
        const double tol = 4.0 * std::sqrt(r.second.second * r.second.second + ref.second * ref.second) + 2e-3 * ref.first;
        CHECK(std::fabs(r.second.first - ref.first) < tol);
    }
}

TEST_CASE("images are bit-identical for any thread count and tile schedule") {
    const Scene scene = load(sphere_scene(R"({"type": "analytic", "kd": 0.4, "eta": 1.5, "alpha": 0.2})",
                                          R"({"type": "sky", "resolution": [64, 32]})", "", kFloor));
    RenderOptions o = quick(4, 4);
    o.threads = 1;
    const Image a = render(scene, o);
    o.threads = 2;
    o.tile_size = 16;
    const Image b = render(scene, o);
    o.threads = 3;
    const Image c = render(scene, o);
    CHECK(a.rgb == b.rgb);
    CHECK(a.rgb == c.rgb);
}

TEST_CASE("model materials: neural_max_depth = 0 renders exactly the analytic part") {
    const std::string model = kSourceDir + "/results/rgl54_hybrid_32x2.safetensors";
    if (!std::ifstream(model).good()) return;  // the fitted model is part of the repository
    const std::string full = R"({"type": "model", "file": "results/rgl54_hybrid_32x2.safetensors", "material": "paper_white_rgb.rgl"})";
    const std::string analytic = R"({"type": "model", "file": "results/rgl54_hybrid_32x2.safetensors", "material": "paper_white_rgb.rgl", "evaluate": "analytic"})";
    const std::string env = R"({"type": "sky", "resolution": [64, 32]})";
    const Scene s_full = load(sphere_scene(full, env, "", kFloor)), s_analytic = load(sphere_scene(analytic, env, "", kFloor));
    RenderOptions o = quick(2, 3);
    RenderStats st_full, st_off, st_analytic;
    const Image img_full = render(s_full, o, &st_full);
    o.neural_max_depth = 0;
    const Image img_off = render(s_full, o, &st_off);
    const Image img_analytic = render(s_analytic, o, &st_analytic);
    CHECK(img_off.rgb == img_analytic.rgb);
    CHECK(img_full.rgb != img_off.rgb);
    CHECK(st_full.network_evals == st_full.brdf_evals);
    CHECK(st_off.network_evals == 0);
    // Rule 2: camera paths start with throughput 1, so a threshold above 1
    // switches the network off everywhere, and one below it keeps it for
    // depth 0 and drops it for paths the floor and the sphere have dimmed.
    o.neural_max_depth = -1;
    o.neural_min_throughput = 1.5f;
    RenderStats st_thr;
    CHECK(render(s_full, o, &st_thr).rgb == img_analytic.rgb);
    CHECK(st_thr.network_evals == 0);
    o.neural_min_throughput = 0.5f;
    render(s_full, o, &st_thr);
    CHECK(st_thr.network_evals > 0);
    CHECK(st_thr.network_evals < st_thr.brdf_evals);
}

TEST_CASE("scene errors name the file and the problem") {
    auto message = [](const std::string& text) -> std::string {
        try {
            load_scene_json(text, ".", "bad.json");
        } catch (const FileError& e) {
            return e.what();
        }
        return "no error";
    };
    CHECK(message("{ not json").rfind("bad.json: invalid JSON", 0) == 0);
    CHECK(message(R"({"objects": []})") == "bad.json: missing key 'camera'");
    const std::string cam = R"("camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]})";
    CHECK(message("{" + cam + R"(, "objects": [{"type": "cube", "material": "x"}]})") ==
          "bad.json: objects[0].type: unknown object type 'cube'; expected sphere, plane, mesh or gltf");
    CHECK(message("{" + cam + R"(, "objects": [{"type": "sphere", "radius": "big", "material": "x"}]})") ==
          "bad.json: objects[0].radius: expected a number, got string");
    CHECK(message("{" + cam + R"(, "objects": [{"type": "sphere", "material": "x"}]})") ==
          "bad.json: objects[0].material: no material named 'x' in 'materials'");
    CHECK(message("{" + cam + R"(, "objects": [{"type": "mesh", "file": "nope.obj", "material": {"type": "analytic"}}]})") ==
          "bad.json: objects[0].file: ./nope.obj: no such file");
    CHECK(message("{" + cam + R"(, "environment": {"type": "file", "file": "sky.exr"}, "objects": [{"type": "sphere", "material": {"type": "analytic"}}]})")
              .rfind("bad.json: environment.file: ./sky.exr: ", 0) == 0);
    CHECK(message("{" + cam + R"(, "objects": [{"type": "sphere", "material": {"type": "measured", "source": "synthetic:gold"}}]})")
              .find("measured materials") != std::string::npos);
    CHECK(message("{" + cam + R"(, "objects": [{"type": "sphere", "raduis": 2, "material": {"type": "analytic"}}]})")
              .rfind("bad.json: objects[0].raduis: unknown key 'raduis'", 0) == 0);
    CHECK(message("{" + cam + R"(, "sampler": "magic", "objects": [{"type": "sphere", "material": {"type": "analytic"}}]})")
              .rfind("bad.json: sampler: unknown sampler 'magic'", 0) == 0);
    CHECK(message("{" + cam + R"(, "objects": [{"type": "sphere", "material": {"type": "analytic", "eta": 0.5}}]})") ==
          "bad.json: objects[0].material: eta[0] = 0.500000 is outside [1.000000, 10.000000]");
}

TEST_CASE("scene settings: one table, checked without narrowing, copied whole into RenderOptions") {
    const std::string cam = R"("camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]})";
    const std::string obj = R"("objects": [{"type": "sphere", "material": {"type": "analytic"}}])";
    auto message = [&](const std::string& settings) -> std::string {
        try {
            load_scene_json("{" + cam + ", " + obj + settings + "}", ".", "s.json");
        } catch (const FileError& e) {
            return e.what();
        }
        return "no error";
    };
    CHECK(message(R"(, "spp": 0)") == "s.json: spp: must be >= 1, got 0");
    // 3000000000 read as an int would wrap to a negative number.
    CHECK(message(R"(, "spp": 3000000000)") == "s.json: spp: must be <= 2147483647, got 3000000000");
    CHECK(message(R"(, "max_depth": -1)") == "s.json: max_depth: must be >= 0, got -1");
    CHECK(message(R"(, "neural_max_depth": -2)") == "s.json: neural_max_depth: must be >= -1, got -2");
    CHECK(message(R"(, "threads": -1)") == "s.json: threads: must be >= 0, got -1");
    CHECK(message(R"(, "rr_depth": 1.5)") == "s.json: rr_depth: expected an integer, got a number (1.5)");
    CHECK(message(R"(, "seed": -1)") == "s.json: seed: must be >= 0, got -1");
    CHECK(message(R"(, "nee": "yes")") == "s.json: nee: expected true or false, got a string");
    CHECK(message(R"(, "neural_min_throughput": -0.5)") == "s.json: neural_min_throughput: must be >= 0, got -0.5");
    CHECK(message(R"(, "tabulated_resolution_deg": 0)") == "s.json: tabulated_resolution_deg: must be >= 1, got 0");
    CHECK(message(R"(, "sampler": 2)") == "s.json: sampler: expected a string, got an integer");
    CHECK(message(R"(, "spp": null)") == "s.json: spp: expected an integer, got null");
    CHECK(message(R"(, "sppp": 4)").rfind("s.json: sppp: unknown key 'sppp' (expected one of: camera, environment, "
                                          "materials, objects, spp, max_depth,", 0) == 0);

    const Scene scene = load_scene_json("{" + cam + ", " + obj + R"(, "spp": 5, "max_depth": 2, "neural_max_depth": 1,
        "neural_min_throughput": 0.25, "sampler": "ggx", "nee": false, "rr_depth": 3, "seed": 4294967296,
        "threads": 3, "tabulated_resolution_deg": 5})", ".", "s.json");
    const RenderSettings& s = scene.settings;
    CHECK(s.spp == 5);
    CHECK(s.max_depth == 2);
    CHECK(s.neural_max_depth == 1);
    CHECK(s.neural_min_throughput == 0.25f);
    CHECK(s.sampler == SamplerKind::Ggx);
    CHECK(scene.materials[0]->sampler_kind() == SamplerKind::Ggx);
    CHECK(!s.nee);
    CHECK(s.rr_depth == 3);
    CHECK(s.seed == 4294967296ull);  // 2^32: not truncated to 0
    CHECK(s.threads == 3);
    CHECK(s.tabulated_resolution_deg == 5);
    const RenderOptions o = RenderOptions::from_scene(s);
    for (const SettingInfo& info : kRenderSettings) {
        CAPTURE(info.name);
        CHECK(get_setting(o, info) == get_setting(s, info));
    }
    RenderOptions bad = o;
    bad.spp = 0;
    CHECK_THROWS_WITH_AS(bad.validate(), "spp: must be >= 1, got 0", std::invalid_argument);
    bad = o;
    bad.neural_min_throughput = std::nanf("");
    CHECK_THROWS_AS(bad.validate(), std::invalid_argument);
    // Keys outside the settings table are read without narrowing too.
    try {
        load_scene_json(R"({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4294967312}, )" + obj + "}",
                        ".", "s.json");
        FAIL("no error");
    } catch (const FileError& e) {
        CHECK(std::string(e.what()) == "s.json: camera.width: must be <= 2147483647, got 4294967312");
    }
}

TEST_CASE("tabulated sampler: one memory budget for all materials, checked before any table is built") {
    // Anisotropic analytic materials (alpha x != y): 210 MB of tables each at 1 degree.
    auto scene = [](int n, int deg) {
        std::string mats, objs;
        for (int i = 0; i < n; ++i) {
            mats += std::string(i ? ", " : "") + "\"m" + std::to_string(i) + R"(": {"type": "analytic", "alpha": [0.1, 0.3]})";
            objs += std::string(i ? ", " : "") + R"({"type": "sphere", "radius": 0.1, "material": "m)" + std::to_string(i) + "\"}";
        }
        return R"({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4},
                   "sampler": "tabulated", "tabulated_resolution_deg": )" + std::to_string(deg) +
               R"(, "materials": {)" + mats + R"(}, "objects": [)" + objs + "]}";
    };
    std::string msg = "no error";
    // Process CPU time, not wall time: a loaded machine (the sanitizer stage beside the Python suite)
    // stretches wall time, while one 1-degree table alone costs seconds of CPU.
    const std::clock_t t0 = std::clock();
    try {
        load_scene_json(scene(100, 1), ".", "many.json");
    } catch (const FileError& e) {
        msg = e.what();
    }
    const double sec = double(std::clock() - t0) / CLOCKS_PER_SEC;
    CHECK(msg == "many.json: sampler: the tabulated sampler's tables for 100 materials (100 anisotropic) at 1 degree "
                 "need ~21 GB, above the budget of 1.1 GB (1 GiB) for all of a scene's tables; use fewer materials, "
                 "a coarser tabulated_resolution_deg (3 fits) or another sampler");
    CHECK(sec < 1.0);  // refused before the first table (seconds each) is built
    // At 18 degrees 100 anisotropic tables take ~1.6 kB each: loaded, tables built.
    const Scene ok = load_scene_json(scene(100, 18), ".", "many.json");
    CHECK(ok.materials.size() == 100);
    CHECK(ok.materials[0]->sampler_memory_bytes() == hbrdf::TabulatedSampler::table_bytes(false, 18));
    CHECK(ok.materials[0]->sampler_memory_bytes() > 0);
}

TEST_CASE("sampler names: the analytic strategies' names plus tabulated") {
    for (SamplerKind k : kSamplerKinds) CHECK(parse_sampler(sampler_name(k)) == k);
    CHECK(parse_sampler("mis") == SamplerKind::Mis);
    CHECK(std::string(sampler_name(SamplerKind::Tabulated)) == "tabulated");
    CHECK(*sampler_strategy(SamplerKind::Ggx) == hbrdf::Strategy::Ggx);
    CHECK(!sampler_strategy(SamplerKind::Tabulated));
    CHECK_THROWS_WITH_AS(parse_sampler("best"), "unknown sampler 'best'; expected cosine, ggx, mis or tabulated",
                         std::invalid_argument);
}

TEST_CASE("EXR written atomically and read back") {
    Image img(5, 3);
    for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) * 0.37f - 1.0f + 1e4f * float(i == 7);
    const std::string path = "hbrdf_render_test_roundtrip.exr";
    write_exr(img, path);
    const Image back = read_image(path);
    CHECK(back.width == 5);
    CHECK(back.height == 3);
    CHECK(back.rgb == img.rgb);  // float32 channels: exact
    std::remove(path.c_str());
    CHECK_THROWS_AS(write_exr(img, "/nonexistent-dir/x.exr"), FileError);
    CHECK(!std::ifstream("/nonexistent-dir/x.exr.tmp").good());
}

TEST_CASE("ray cones: a plane's and a sphere's uv scale and a camera ray's footprint") {
    // A plane of size 2 facing a camera 5 away: 0.5 uv units per world unit; the centre pixel's cone
    // is 2 tan(20 deg) / 64 x 5 wide there, facing the ray.
    Scene scene = load(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "fov_deg": 40, "width": 64, "height": 64},
        "environment": {"type": "constant", "radiance": 1}, "materials": {"m": {"type": "analytic"}},
        "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "size": 2, "material": "m"},
                    {"type": "sphere", "center": [8, 0, -20], "radius": 1.5, "material": "m"}]})");
    const Ray centre = scene.camera.generate(32.0f, 32.0f);
    SurfaceHit hit;
    REQUIRE(scene.intersect(centre.origin, centre.dir, &hit));
    CHECK(hit.uv_scale_log2 == doctest::Approx(std::log2(0.5)).epsilon(1e-6));
    const double spread = 2.0 * std::tan(20.0 * 3.14159265358979323846 / 180.0) / 64.0;
    CHECK(scene.camera.pixel_spread() == doctest::Approx(spread).epsilon(1e-6));
    CHECK(cone_footprint_log2(float(spread) * hit.t, dot(hit.ng, centre.dir), hit.uv_scale_log2) ==
          doctest::Approx(std::log2(0.5 * 5.0 * spread)).epsilon(1e-5));
    // Slanted 60 degrees: the footprint stretches by 1 / cos 60 = 2 along the surface (+1 in log2).
    CHECK(cone_footprint_log2(1.0f, 0.5f, 0.0f) == doctest::Approx(1.0).epsilon(1e-6));
    CHECK(cone_footprint_log2(0.0f, 1.0f, 0.0f) == kPointFootprint);
    CHECK(camera_cone_spread(1.0f, 1) == 1.0f);
    CHECK(camera_cone_spread(1.0f, 16) == 0.25f);
    CHECK(camera_cone_spread(1.0f, 4096) == 0.125f);
    // The sphere's scale against its own uv map measured by the tracer: three hits a few thousandths
    // apart, their uv triangle's area over their world triangle's, at several latitudes.
    for (const Vec2<float> at : {Vec2<float>(8.3f, -0.2f), Vec2<float>(7.4f, 0.9f), Vec2<float>(8.6f, 1.3f)}) {
        const Vec3f target(at.x, at.y, -20.0f), o = centre.origin;
        SurfaceHit h[3];
        const Vec3f offsets[3] = {Vec3f(0.0f), Vec3f(2e-3f, 0.0f, 0.0f), Vec3f(0.0f, 2e-3f, 0.0f)};
        for (int k = 0; k < 3; ++k) REQUIRE(scene.intersect(o, glm::normalize(target + offsets[k] - o), &h[k]));
        const float measured = triangle_uv_scale_log2(h[0].p, h[1].p, h[2].p, h[0].uv, h[1].uv, h[2].uv);
        CHECK(h[0].uv_scale_log2 == doctest::Approx(measured).epsilon(2e-3));
        // The anisotropic footprint's uv gradients (sphere_uv_gradients) against the same hits' uv
        // differences: du = du_dp . dp to first order (5 of the 6 v checks fail with its gradient negated).
        for (int k = 1; k < 3; ++k) {
            const Vec3f dp = h[k].p - h[0].p;
            const double du = double(h[k].uv.x) - h[0].uv.x, dv = double(h[k].uv.y) - h[0].uv.y;
            const double scale = std::max(std::fabs(du), std::fabs(dv));
            CHECK(std::fabs(double(dot(h[0].du_dp, dp)) - du) <= 2e-2 * scale);
            CHECK(std::fabs(double(dot(h[0].dv_dp, dp)) - dv) <= 2e-2 * scale);
        }
    }
    // The plane's: 0.5 uv units per world unit along its tangent and bitangent, orthogonal, nothing
    // along its normal (+z).
    CHECK(std::sqrt(dot(hit.du_dp, hit.du_dp)) == doctest::Approx(0.5f).epsilon(1e-5));
    CHECK(std::sqrt(dot(hit.dv_dp, hit.dv_dp)) == doctest::Approx(0.5f).epsilon(1e-5));
    CHECK(std::fabs(dot(hit.du_dp, hit.dv_dp)) + std::fabs(hit.du_dp.z) + std::fabs(hit.dv_dp.z) < 1e-6f);
}
