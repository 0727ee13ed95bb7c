// Tests of the tracer's point and directional lights (light.hpp, docs/RENDERING.md "Lights") and of
// the direct-light comparison mode (max_depth 1, "shadows": false, "pixel_jitter": false).
// Independent reference: f_a in double from the textbook formulas of CONVENTIONS.md (Walter's GGX,
// separable Smith, the exact dielectric Fresnel in its g = sqrt(eta^2 - 1 + c^2) form, none of the
// library's stable rewrites), the plane intersected in double, and the delta lights' closed forms
// f I cos / d^2 and f E cos, per pixel.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <string>

#include "hybridbrdf/render/render.hpp"

using namespace hbrdf::render;

namespace {

const std::string kLightsSourceDir = HBRDF_SOURCE_DIR;

struct D3 {
    double x, y, z;
};
D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 operator-(D3 a, D3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
D3 operator*(D3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot3(D3 a, D3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross3(D3 a, D3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
D3 unit(D3 a) { return a * (1.0 / std::sqrt(dot3(a, a))); }
D3 d3(const hbrdf::Vec3<float>& v) { return {v.x, v.y, v.z}; }

constexpr double kPi = 3.14159265358979323846;

// f_a of one channel, double, textbook forms (CONVENTIONS.md "Analytic component f_a").
double fa_textbook(D3 wi, D3 wo, double kd, double eta, double ax, double ay) {
    const D3 h = unit(wi + wo);
    const double e = h.x * h.x / (ax * ax) + h.y * h.y / (ay * ay) + h.z * h.z;
    const double D = 1.0 / (kPi * ax * ay * e * e);
    auto G1 = [&](D3 w) { return 2.0 / (1.0 + std::sqrt(1.0 + (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / (w.z * w.z))); };
    const double c = dot3(wo, h), g = std::sqrt(eta * eta - 1.0 + c * c);
    const double a = (g - c) / (g + c), b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    const double F = 0.5 * a * a * (1.0 + b * b);
    return kd / kPi + F * D * G1(wi) * G1(wo) / (4.0 * wi.z * wo.z);
}

// An anisotropic analytic material on the plane y = 0 (its tangent along (1, 0, 1), so that the
// anisotropy's axis is not a world axis), seen obliquely; no environment; one bounce.
const double kKd[3] = {0.3, 0.5, 0.2}, kEta[3] = {1.5, 2.0, 3.0}, kAx = 0.15, kAy = 0.45;

std::string plane_scene(const std::string& lights, const std::string& extra = "", const std::string& more_objects = "") {
    return R"({"camera": {"position": [0.4, 2.0, 2.5], "look_at": [0, 0, 0], "fov_deg": 40, "width": 24, "height": 18},
              "environment": {"type": "constant", "radiance": 0},
              "materials": {"m": {"type": "analytic", "kd": [0.3, 0.5, 0.2], "eta": [1.5, 2.0, 3.0], "alpha": [0.15, 0.45]}},
              "lights": )" + lights + R"(,
              "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 1], "size": 40, "material": "m"})" +
           more_objects + R"(], "max_depth": 1, "spp": 1, "pixel_jitter": false, "threads": 2)" + extra + "}";
}

Scene load_lit(const std::string& text) { return load_scene_json(text, kLightsSourceDir, "<test>"); }

Image draw_lit(const Scene& scene) {
    RenderOptions o = RenderOptions::from_scene(scene.settings);
    o.quiet = true;
    return render(scene, o);
}

// The radiance the camera ray through pixel (x, y)'s centre sees on the plane, per channel, from
// a light given by `light(p) -> (wi_world, factor)` where factor is I / d^2 or E.
template <typename Light> void expect_closed_form(const Scene& scene, const Image& img, Light light) {
    const D3 n{0, 1, 0}, t = unit(D3{1, 0, 1}), b = cross3(n, t);
    auto local = [&](D3 w) { return D3{dot3(w, t), dot3(w, b), dot3(w, n)}; };
    int lit = 0;
    double worst = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const Ray ray = scene.camera.generate(float(x) + 0.5f, float(y) + 0.5f);
            const D3 o = d3(ray.origin), d = unit(d3(ray.dir));
            const D3 p = o + d * (-o.y / d.y);
            const auto [wi_world, factor] = light(p);
            const D3 wi = local(wi_world), wo = local(d * -1.0);
            for (int c = 0; c < 3; ++c) {
                const double want = wi.z > 0 ? fa_textbook(wi, wo, kKd[c], kEta[c], kAx, kAy) * factor[c] * wi.z : 0.0;
                const double got = img.at(x, y)[c];
                const double err = std::fabs(got - want) / std::max(want, 1e-6);
                worst = std::max(worst, err);
                if (err > 2e-3) FAIL_CHECK("pixel (" << x << ", " << y << ") channel " << c << ": " << got << " vs " << want);
            }
            lit += wi.z > 0 ? 1 : 0;
        }
    MESSAGE("worst relative error " << worst);
    CHECK(lit > img.width * img.height / 2);
}

}  // namespace

TEST_CASE("point light over an anisotropic plane: f I cos / d^2 per pixel (float64 closed form)") {
    const double I[3] = {2.0, 3.0, 4.0};
    const D3 at{0.3, 1.5, -0.2};
    const Scene scene = load_lit(plane_scene(R"([{"type": "point", "position": [0.3, 1.5, -0.2], "intensity": [2, 3, 4]}])"));
    expect_closed_form(scene, draw_lit(scene), [&](D3 p) {
        const D3 to = at - p;
        const double d2 = dot3(to, to);
        return std::make_pair(unit(to), std::array<double, 3>{I[0] / d2, I[1] / d2, I[2] / d2});
    });
}

TEST_CASE("directional light over an anisotropic plane: f E cos per pixel (float64 closed form)") {
    const Scene scene = load_lit(plane_scene(R"([{"type": "directional", "direction": [1, 2, -0.5], "irradiance": [1.5, 0.5, 2]}])"));
    expect_closed_form(scene, draw_lit(scene), [&](D3) {
        return std::make_pair(unit(D3{1, 2, -0.5}), std::array<double, 3>{1.5, 0.5, 2.0});
    });
}

TEST_CASE("point light: doubling the distance quarters the radiance") {
    // A Lambert plane (eta 1: no specular), the light straight above the point the centre pixel
    // sees (odd width and height: the centre pixel's centre is the look_at point).
    auto centre = [](double h) {
        const std::string text = R"({"camera": {"position": [0, 3, 1], "look_at": [0, 0, 0], "fov_deg": 30, "width": 5, "height": 5},
            "environment": {"type": "constant", "radiance": 0},
            "lights": [{"type": "point", "position": [0, )" + std::to_string(h) + R"(, 0], "intensity": 7}],
            "objects": [{"type": "plane", "size": 10, "material": {"type": "analytic", "kd": 0.6, "eta": 1, "alpha": 0.5}}],
            "max_depth": 1, "spp": 1, "pixel_jitter": false})";
        const Scene scene = load_lit(text);
        return double(draw_lit(scene).at(2, 2)[0]);
    };
    const double near = centre(0.5), far = centre(1.0), farther = centre(2.0);
    CHECK(near == doctest::Approx(0.6 / kPi * 7 / 0.25).epsilon(1e-5));
    CHECK(near / far == doctest::Approx(4.0).epsilon(1e-5));
    CHECK(far / farther == doctest::Approx(4.0).epsilon(1e-5));
}

TEST_CASE("shadows: an occluder darkens the plane; \"shadows\": false skips the delta lights' shadow rays") {
    const std::string light = R"([{"type": "point", "position": [0, 3, 0], "intensity": 10}])";
    const std::string ball = R"(, {"type": "sphere", "center": [0, 1, 0], "radius": 0.4, "material": "m"})";
    const Scene bare = load_lit(plane_scene(light)), shadowed = load_lit(plane_scene(light, "", ball)),
                unshadowed = load_lit(plane_scene(light, R"(, "shadows": false)", ball));
    const Image a = draw_lit(bare), b = draw_lit(shadowed), c = draw_lit(unshadowed);
    int in_shadow = 0, on_plane = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            SurfaceHit hit;
            const Ray ray = shadowed.camera.generate(float(x) + 0.5f, float(y) + 0.5f);
            REQUIRE(shadowed.intersect(ray.origin, ray.dir, &hit));
            if (hit.p.y > 1e-3f) continue;  // the camera sees the ball here
            ++on_plane;
            for (int ch = 0; ch < 3; ++ch) CHECK(c.at(x, y)[ch] == a.at(x, y)[ch]);  // no shadow rays: as if no ball
            if (b.at(x, y)[0] == 0.0f && a.at(x, y)[0] > 0.0f) ++in_shadow;
            else CHECK(b.at(x, y)[0] == a.at(x, y)[0]);
        }
    CHECK(on_plane > 300);
    CHECK(in_shadow > 10);  // the ball's shadow, a disc of radius ~0.6 around the origin
}

TEST_CASE("pixel_jitter false: delta lights, one bounce: the same image for any seed, sampler and nee") {
    const std::string lights = R"([{"type": "point", "position": [0.3, 1.5, -0.2], "intensity": [2, 3, 4]},
                                    {"type": "directional", "direction": [1, 2, -0.5], "irradiance": [1.5, 0.5, 2]}])";
    const Scene scene = load_lit(plane_scene(lights));
    RenderOptions o = RenderOptions::from_scene(scene.settings);
    o.quiet = true;
    const Image ref = render(scene, o);
    o.seed = 12345;
    CHECK(render(scene, o).rgb == ref.rgb);
    o.nee = false;  // "nee" is the environment's; the delta lights are always sampled
    CHECK(render(scene, o).rgb == ref.rgb);
    o.spp = 3;  // three equal samples; their mean rounds within an ulp or two
    const Image three = render(scene, o);
    for (std::size_t i = 0; i < ref.rgb.size(); ++i) CHECK(three.rgb[i] == doctest::Approx(ref.rgb[i]).epsilon(1e-6));
    o.spp = 1;
    o.pixel_jitter = true;  // the jitter is what the seed moves
    CHECK(render(scene, o).rgb != ref.rgb);
    for (const char* sampler : {"cosine", "ggx", "mis", "tabulated"}) {
        CAPTURE(sampler);
        const Scene s = load_lit(plane_scene(lights, std::string(R"(, "tabulated_resolution_deg": 15, "sampler": ")") + sampler + "\""));
        CHECK(draw_lit(s).rgb == ref.rgb);
    }
}

TEST_CASE("delta lights with a hybrid model material: f(wo, wi) in the library's argument order") {
    const std::string file = kLightsSourceDir + "/results/rgl54_hybrid_32x2.safetensors";
    if (!std::ifstream(file).good()) return;  // the fitted model is part of the repository
    const std::string text = R"({"camera": {"position": [0.4, 2.0, 2.5], "look_at": [0, 0, 0], "fov_deg": 40, "width": 16, "height": 12},
        "environment": {"type": "constant", "radiance": 0},
        "materials": {"m": {"type": "model", "file": "results/rgl54_hybrid_32x2.safetensors", "material": "cc_ibiza_sunset_rgb.rgl"}},
        "lights": [{"type": "point", "position": [-0.8, 1.2, 0.5], "intensity": 3}],
        "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 1], "size": 40, "material": "m"}],
        "max_depth": 1, "spp": 1, "pixel_jitter": false})";
    const Scene scene = load_lit(text);
    const Image img = draw_lit(scene);
    const hbrdf::HybridModel model = hbrdf::HybridModel::load(file);
    const int m = model.find("cc_ibiza_sunset_rgb.rgl");
    REQUIRE(m >= 0);
    const D3 n{0, 1, 0}, t = unit(D3{1, 0, 1}), b = cross3(n, t), at{-0.8, 1.2, 0.5};
    auto local = [&](D3 w) { return hbrdf::Vec3<float>(float(dot3(w, t)), float(dot3(w, b)), float(dot3(w, n))); };
    double worst = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const Ray ray = scene.camera.generate(float(x) + 0.5f, float(y) + 0.5f);
            const D3 o = d3(ray.origin), d = unit(d3(ray.dir)), p = o + d * (-o.y / d.y), to = at - p;
            const double d2 = dot3(to, to);
            const auto wi = local(unit(to)), wo = local(d * -1.0);
            const auto f = model.eval(m, wi, wo);
            for (int c = 0; c < 3; ++c) {
                const double want = double(f[c]) * 3.0 * double(wi.z) / d2, got = img.at(x, y)[c];
                worst = std::max(worst, std::fabs(got - want) / std::max(want, 1e-6));
            }
        }
    MESSAGE("worst relative error " << worst);
    CHECK(worst < 5e-3);
}

TEST_CASE("lights: the scene loader's one-line refusals") {
    auto message = [](const std::string& lights) -> std::string {
        try {
            load_scene_json(plane_scene(lights), ".", "bad.json");
        } catch (const FileError& e) {
            return e.what();
        }
        return "no error";
    };
    CHECK(message(R"({"type": "point"})") == "bad.json: lights: expected an array of lights");
    CHECK(message(R"([{"type": "spot", "position": [0, 1, 0]}])") ==
          "bad.json: lights[0].type: unknown light type 'spot'; expected point or directional");
    CHECK(message(R"([{"type": "point", "position": [0, 1], "intensity": 1}])") ==
          "bad.json: lights[0].position: expected an array of 3 numbers");
    CHECK(message(R"([{"type": "point", "position": [0, 1, 0], "intensity": [1, -1, 1]}])") ==
          "bad.json: lights[0].intensity[1]: must be >= 0, got -1");
    CHECK(message(R"([{"type": "point", "position": [0, 1, 0]}])") == "bad.json: lights[0]: missing key 'intensity'");
    // JSON holds no infinity; 1e400 overflows the parser's double (it used to escape as a bare json exception).
    CHECK(message(R"([{"type": "point", "position": [0, 1e400, 0], "intensity": 1}])") ==
          "bad.json: invalid JSON: [json.exception.out_of_range.406] number overflow parsing '1e400'");
    CHECK(message(R"([{"type": "point", "position": [0, 3e38, 0], "intensity": 1}])") ==
          "bad.json: lights[0].position[1]: must be within +-1e+12 (limits.hpp, kMaxCoordinate), got 3e+38");
    CHECK(message(R"([{"type": "point", "position": [0, 1e13, 0], "intensity": 1}])") ==
          "bad.json: lights[0].position[1]: must be within +-1e+12 (limits.hpp, kMaxCoordinate), got 1e+13");
    CHECK(message(R"([{"type": "directional", "direction": [0, 0, 0], "irradiance": 1}])") ==
          "bad.json: lights[0].direction: must not be zero (it points from the scene toward the light)");
    CHECK(message(R"([{"type": "directional", "direction": [0, 1, 0], "irradiance": 1, "color": 2}])") ==
          "bad.json: lights[0].color: unknown key 'color' (expected one of: type, direction, irradiance)");
    CHECK(message(R"([{"type": "directional", "direction": [0, 1, 0], "irradiance": "bright"}])") ==
          "bad.json: lights[0].irradiance: expected an array of 3 numbers or a number");
    std::string many = "[";
    for (int i = 0; i < 1025; ++i) many += std::string(i ? "," : "") + R"({"type": "directional", "direction": [0, 1, 0], "irradiance": 1})";
    CHECK(message(many + "]") ==
          "bad.json: lights: 1025 lights, above the limit of 1024 (each costs a shadow ray and a BRDF evaluation at every surface interaction)");
}

TEST_CASE("a black environment is neither sampled nor traced toward on the last bounce") {
    const Scene scene = load_lit(plane_scene(R"([{"type": "directional", "direction": [0, 1, 0], "irradiance": 1}])"));
    RenderOptions o = RenderOptions::from_scene(scene.settings);
    o.quiet = true;
    RenderStats st;
    render(scene, o, &st);
    const std::uint64_t pixels = 24 * 18;
    CHECK(st.rays == pixels);         // camera rays only: no BSDF continuation that could find only black
    CHECK(st.shadow_rays == pixels);  // one per light, none toward the environment
    CHECK(st.brdf_evals == pixels);   // the light's pair alone
}
