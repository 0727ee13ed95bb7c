// hybridbrdf renderer — the wavefront path tracer of integrator.hpp.
#include "hybridbrdf/render/integrator.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "hybridbrdf/render/progress.hpp"
#include "hybridbrdf/render/ray_cone.hpp"
#include "hybridbrdf/render/rng.hpp"

namespace hbrdf::render {

namespace {

// Power heuristic (beta = 2) weight of strategy a against b. In double:
// GGX densities at alpha = 1e-4 reach 1e15 and their square overflows float.
float power_heuristic(float pdf_a, float pdf_b) {
    const double a = double(pdf_a) * double(pdf_a), b = double(pdf_b) * double(pdf_b);
    return a + b > 0.0 ? float(a / (a + b)) : 0.0f;
}

float max_component(const Vec3f& v) { return std::max(v.x, std::max(v.y, v.z)); }

bool finite3(const Vec3f& v) { return is_finite(v.x) && is_finite(v.y) && is_finite(v.z); }

struct Path {
    Vec3f origin, dir, throughput;
    float prev_pdf;  // density of the BSDF sample that made `dir`
    int local_pixel; // index in the tile
    int sample;      // sample index in [0, spp)
    std::uint64_t pixel;
};

// What one path needs from its material at this bounce.
struct Shading {
    SurfaceHit hit;
    Footprint footprint;  // where the hit reads its textures (ray_cone.hpp): a point past the camera ray
    Vec3f wo;                 // local
    Vec3f wi_light, light_radiance;
    float light_pdf = 0;
    bool light_ok = false;    // NEE sample unoccluded and above both horizons
    Vec3f wi_bsdf, wi_bsdf_world;
    float bsdf_pdf = 0;
    bool bsdf_ok = false;
    bool network = false;
    Vec3f f_light{0.0f}, f_bsdf{0.0f};
    std::size_t delta_begin = 0, delta_end = 0;  // this path's unoccluded delta-light samples in deltas_
};

// A point or directional light seen from a hit (light.hpp): it adds f(wo, wi) * scale, where scale
// is I cos(theta_i) / d^2 for a point light and E cos(theta_i) for a directional one.
struct DeltaSample {
    Vec3f wi;     // local
    Vec3f scale;
    Vec3f f{0.0f};
};

struct Counters {
    std::uint64_t rays = 0, shadow_rays = 0, brdf_evals = 0, network_evals = 0;
};

// Per-thread renderer: buffers reused from tile to tile.
class TileRenderer {
public:
    TileRenderer(const Scene& scene, const RenderOptions& options)
        : scene_(scene), opt_(options), cone_spread_(camera_cone_spread(scene.camera.pixel_spread(), options.spp)) {}

    void render_tile(int x0, int y0, int x1, int y1, Image& image, Counters& counters) {
        const int tw = x1 - x0, th = y1 - y0, n_pixels = tw * th;
        accum_.assign(std::size_t(n_pixels) * 3, 0.0f);
        const int per_wave = std::max(1, opt_.max_paths_per_wave / n_pixels);
        // s0 + per_wave may exceed INT_MAX when spp is near it: step to s1, never past spp.
        for (int s0 = 0, s1; s0 < opt_.spp; s0 = s1) {
            throw_if_cancelled(opt_.cancel);  // a tile of many samples holds many waves
            s1 = s0 + std::min(per_wave, opt_.spp - s0);
            paths_.clear();
            for (int s = s0; s < s1; ++s)
                for (int ly = 0; ly < th; ++ly)
                    for (int lx = 0; lx < tw; ++lx) {
                        const std::uint64_t pixel = std::uint64_t(y0 + ly) * std::uint64_t(image.width) + std::uint64_t(x0 + lx);
                        const PathRandom rng{opt_.seed, pixel, std::uint64_t(s)};
                        // A box filter over the pixel; pixel_jitter 0: its centre (a raster frame's sample).
                        const float jx = opt_.pixel_jitter ? rng.camera(0) : 0.5f, jy = opt_.pixel_jitter ? rng.camera(1) : 0.5f;
                        const Ray ray = scene_.camera.generate(float(x0 + lx) + jx, float(y0 + ly) + jy);
                        paths_.push_back(Path{ray.origin, ray.dir, Vec3f(1.0f), 0.0f, ly * tw + lx, s, pixel});
                    }
            trace_wave(counters);
        }
        const float inv_spp = 1.0f / float(opt_.spp);
        for (int ly = 0; ly < th; ++ly)
            for (int lx = 0; lx < tw; ++lx) {
                float* out = image.at(x0 + lx, y0 + ly);
                const float* a = &accum_[std::size_t(ly * tw + lx) * 3];
                for (int c = 0; c < 3; ++c) out[c] = a[c] * inv_spp;
            }
    }

private:
    void add(const Path& path, const Vec3f& L) {
        if (!finite3(L)) return;  // a single non-finite sample must not poison the pixel
        float* a = &accum_[std::size_t(path.local_pixel) * 3];
        a[0] += L.x;
        a[1] += L.y;
        a[2] += L.z;
    }

    void trace_wave(Counters& counters) {
        const EnvironmentLight& env = scene_.environment;
        // A black environment (radiance 0: "no environment", a scene lit by delta lights alone) is
        // neither looked up nor sampled, and the last bounce's BSDF sample, which could only find
        // it, is not drawn.
        const bool env_black = !(env.brightest() > 0.0f);
        for (int depth = 0; !paths_.empty(); ++depth) {
            // 1. Extension rays. Escaped paths see the environment: weight 1 for
            // camera rays and without NEE, else the MIS weight of BSDF sampling.
            shading_.resize(paths_.size());
            hit_.assign(paths_.size(), 0);
            for (std::size_t k = 0; k < paths_.size(); ++k) {
                Path& p = paths_[k];
                ++counters.rays;
                if (scene_.intersect(p.origin, p.dir, &shading_[k].hit)) {
                    hit_[k] = 1;
                    continue;
                }
                if (env_black) continue;
                const float w = (depth == 0 || !opt_.nee) ? 1.0f : power_heuristic(p.prev_pdf, env.pdf(p.dir));
                add(p, p.throughput * env.eval(p.dir) * w);
            }
            if (depth >= opt_.max_depth) break;

            // 2. Light and BSDF directions; shadow rays.
            deltas_.clear();
            const bool last_useless = env_black && depth + 1 >= opt_.max_depth;
            for (std::size_t k = 0; k < paths_.size(); ++k) {
                if (!hit_[k]) continue;
                const Path& p = paths_[k];
                Shading& s = shading_[k];
                s.delta_begin = s.delta_end = deltas_.size();
                const Material& mat = *scene_.materials[std::size_t(s.hit.material)];
                const PathRandom rng{opt_.seed, p.pixel, std::uint64_t(p.sample)};
                s.wo = s.hit.shading.to_local(-p.dir);
                s.network = use_network(opt_, depth, p.throughput);
                // Camera rays carry their pixel's cone (width spread x t at the hit: it starts at the
                // pinhole). Past the first bounce the footprint is a point, level 0: the BSDF lobe
                // spreads the paths far wider than any cone, and Monte Carlo integration over it
                // already averages the texels there (docs/RENDERING.md, "Texture footprints").
                s.footprint = opt_.mip_lod && depth == 0 ? camera_footprint(p, s.hit) : Footprint();
                s.light_ok = s.bsdf_ok = false;
                s.f_light = s.f_bsdf = Vec3f(0.0f);
                if (!(s.wo.z > 0.0f)) continue;  // shading normal turned away from the viewer: black
                sample_delta_lights(s, counters);
                if (opt_.nee && !env_black) {
                    const LightSample ls = env.sample(Vec2<float>(rng.bounce(depth, kDimLight0), rng.bounce(depth, kDimLight1)));
                    s.wi_light = s.hit.shading.to_local(ls.wi);
                    s.light_pdf = ls.pdf;
                    s.light_radiance = ls.radiance;
                    if (ls.pdf > 0.0f && s.wi_light.z > 0.0f && dot(s.hit.ng, ls.wi) > 0.0f && max_component(ls.radiance) > 0.0f) {
                        ++counters.shadow_rays;
                        s.light_ok = !scene_.occluded(Scene::offset_origin(s.hit, ls.wi), ls.wi);
                    }
                }
                if (last_useless) continue;
                const BrdfSample bs = mat.sample_at(s.wo, Vec2<float>(rng.bounce(depth, kDimBsdf0), rng.bounce(depth, kDimBsdf1)),
                                                    s.hit.uv, s.footprint);
                s.wi_bsdf = bs.wi;
                s.bsdf_pdf = bs.pdf;
                s.wi_bsdf_world = s.hit.shading.to_world(bs.wi);
                // Directions below the geometric surface would leak light through it.
                s.bsdf_ok = bs.pdf > 0.0f && bs.wi.z > 0.0f && dot(s.hit.ng, s.wi_bsdf_world) > 0.0f;
            }

            // 3. Batched evaluation, one call per (material, mode), pairs in path order.
            evaluate(counters);

            // 4. NEE contributions and the next rays.
            std::size_t alive = 0;
            for (std::size_t k = 0; k < paths_.size(); ++k) {
                if (!hit_[k]) continue;
                Path p = paths_[k];
                const Shading& s = shading_[k];
                const Material& mat = *scene_.materials[std::size_t(s.hit.material)];
                // Delta lights: no MIS weight, BSDF sampling never finds them.
                for (std::size_t j = s.delta_begin; j < s.delta_end; ++j) add(p, p.throughput * deltas_[j].f * deltas_[j].scale);
                if (s.light_ok) {
                    const float w = power_heuristic(s.light_pdf, mat.pdf_at(s.wi_light, s.wo, s.hit.uv, s.footprint));
                    add(p, p.throughput * s.f_light * s.light_radiance * (s.wi_light.z * w / s.light_pdf));
                }
                if (!s.bsdf_ok) continue;
                p.throughput *= s.f_bsdf * (s.wi_bsdf.z / s.bsdf_pdf);
                if (!(max_component(p.throughput) > 0.0f) || !finite3(p.throughput)) continue;
                if (opt_.rr_depth >= 0 && depth >= opt_.rr_depth) {
                    const float q = std::min(0.95f, max_component(p.throughput));
                    const PathRandom rng{opt_.seed, p.pixel, std::uint64_t(p.sample)};
                    if (rng.bounce(depth, kDimRoulette) >= q) continue;
                    p.throughput /= q;
                }
                p.origin = Scene::offset_origin(s.hit, s.wi_bsdf_world);
                p.dir = s.wi_bsdf_world;
                p.prev_pdf = s.bsdf_pdf;
                paths_[alive++] = p;  // alive <= k: compaction in place keeps the order
            }
            paths_.resize(alive);
        }
    }

    // The texture footprint of a camera ray's hit (ray_cone.hpp): the cone's width, and with
    // "anisotropic" >= 2 the pixel's two axes on the surface in uv from ray differentials (the ray's
    // unnormalised direction D = dir / (dir . forward) steps by right x spread per pixel across,
    // -up x spread down; spread is the cone's, so narrowed with spp like it) and the offset to the
    // footprint's centre: pulled from the sample's point toward the pixel's centre by the footprint's
    // share of the pixel, (0.5 - jitter) x spread / pixel_spread pixels, so that the footprints of
    // uniformly jittered samples stay inside their pixel and at 1 spp the lookup is the pixel's own
    // box (docs/RENDERING.md, "Anisotropic footprints").
    Footprint camera_footprint(const Path& p, const SurfaceHit& hit) const {
        Footprint fp;
        fp.cone_log2 = cone_footprint_log2(cone_spread_ * hit.t, dot(hit.ng, p.dir), hit.uv_scale_log2);
        if (opt_.anisotropic < 2 || !(fp.cone_log2 > kPointFootprint)) return fp;
        const PinholeCamera& camera = scene_.camera;
        const float cos_forward = dot(p.dir, camera.forward());
        const Vec3f D = p.dir / cos_forward;
        const float t_D = hit.t * cos_forward;
        const Vec3f dp_dx = ray_differential_dp(D, t_D, camera.right() * cone_spread_, hit.ng);
        const Vec3f dp_dy = ray_differential_dp(D, t_D, camera.up() * -cone_spread_, hit.ng);
        fp.duv_dx = Vec2<float>(dot(hit.du_dp, dp_dx), dot(hit.dv_dp, dp_dx));
        fp.duv_dy = Vec2<float>(dot(hit.du_dp, dp_dy), dot(hit.dv_dp, dp_dy));
        fp.max_probes = opt_.anisotropic;
        if (opt_.pixel_jitter) {
            const PathRandom rng{opt_.seed, p.pixel, std::uint64_t(p.sample)};
            fp.centre = fp.duv_dx * (0.5f - rng.camera(0)) + fp.duv_dy * (0.5f - rng.camera(1));
        }
        return fp;
    }

    // Next-event estimation toward every point and directional light: a direction above both the
    // shading and the geometric horizon (the side the ray arrived on: surfaces are two-sided), a
    // shadow ray unless `shadows` is off, and the light's delta-distribution factor. Appends the
    // unoccluded ones to deltas_ as s's range.
    void sample_delta_lights(Shading& s, Counters& counters) {
        const DeltaLights& lights = scene_.lights;
        auto visible_at_infinity = [&](const Vec3f& wi_world) {
            ++counters.shadow_rays;
            return !scene_.occluded(Scene::offset_origin(s.hit, wi_world), wi_world);
        };
        // From the offset origin (it moves by 2e-5 (1 + |p|), which far from the world's origin can
        // exceed a nearby light's distance), stopping just short of the light.
        auto visible_point = [&](const Vec3f& wi_world, const Vec3f& light) {
            ++counters.shadow_rays;
            const Vec3f origin = Scene::offset_origin(s.hit, wi_world), to = light - origin;
            const float dist = std::sqrt(dot(to, to));
            return !(dist > 0.0f) || !scene_.occluded(origin, to / dist, dist * (1.0f - 1e-4f));
        };
        auto above = [&](const Vec3f& wi_world, const Vec3f& wi) { return wi.z > 0.0f && dot(s.hit.ng, wi_world) > 0.0f; };
        for (const PointLight& light : lights.points) {
            const Vec3f to = light.position - s.hit.p;
            const float d2 = dot(to, to);
            if (!(d2 > 0.0f) || !(max_component(light.intensity) > 0.0f)) continue;
            const float d = std::sqrt(d2);
            const Vec3f wi_world = to / d;
            const Vec3f wi = s.hit.shading.to_local(wi_world);
            if (!above(wi_world, wi)) continue;
            if (opt_.shadows && !visible_point(wi_world, light.position)) continue;
            deltas_.push_back(DeltaSample{wi, light.intensity * (wi.z / d2)});
        }
        for (const DirectionalLight& light : lights.directionals) {
            const Vec3f wi = s.hit.shading.to_local(light.direction);
            if (!(max_component(light.irradiance) > 0.0f) || !above(light.direction, wi)) continue;
            if (opt_.shadows && !visible_at_infinity(light.direction)) continue;
            deltas_.push_back(DeltaSample{wi, light.irradiance * wi.z});
        }
        s.delta_end = deltas_.size();
    }

    // Batched evaluation. A counting sort of the hit paths by (material, mode)
    // makes each batch one contiguous run of path indices, so no material
    // rescans every path. The sort is stable: a batch holds its pairs in path
    // order, the same batches as a scan in path order would build.
    void evaluate(Counters& counters) {
        const std::size_t n_keys = 2 * scene_.materials.size();
        auto key = [&](std::size_t k) {
            return 2 * std::size_t(shading_[k].hit.material) + (shading_[k].network ? 0 : 1);
        };
        bucket_.assign(n_keys + 1, 0);
        for (std::size_t k = 0; k < paths_.size(); ++k)
            if (hit_[k]) ++bucket_[key(k) + 1];
        for (std::size_t b = 0; b < n_keys; ++b) bucket_[b + 1] += bucket_[b];  // bucket_[b]: start of key b
        order_.resize(bucket_[n_keys]);
        cursor_.assign(bucket_.begin(), bucket_.end() - 1);
        for (std::size_t k = 0; k < paths_.size(); ++k)
            if (hit_[k]) order_[cursor_[key(k)]++] = k;

        for (std::size_t b = 0; b < n_keys; ++b) {
            const Material& mat = *scene_.materials[b / 2];
            const EvalMode mode = b % 2 == 0 ? EvalMode::Full : EvalMode::Analytic;
            wi_.clear();
            wo_.clear();
            uv_.clear();
            footprint_.clear();
            slots_.clear();
            auto push = [&](const Vec3f& wi, const Shading& s, Vec3f* slot) {
                wi_.insert(wi_.end(), {wi.x, wi.y, wi.z});
                wo_.insert(wo_.end(), {s.wo.x, s.wo.y, s.wo.z});
                uv_.insert(uv_.end(), {s.hit.uv.x, s.hit.uv.y});
                footprint_.push_back(s.footprint);
                slots_.push_back(slot);
            };
            for (std::size_t i = bucket_[b]; i < bucket_[b + 1]; ++i) {
                Shading& s = shading_[order_[i]];
                for (std::size_t j = s.delta_begin; j < s.delta_end; ++j) push(deltas_[j].wi, s, &deltas_[j].f);
                if (s.light_ok) push(s.wi_light, s, &s.f_light);
                if (s.bsdf_ok) push(s.wi_bsdf, s, &s.f_bsdf);
            }
            if (slots_.empty()) continue;
            f_.resize(wi_.size());
            mat.eval_at(slots_.size(), uv_.data(), footprint_.data(), wi_.data(), wo_.data(), f_.data(), mode);
            counters.brdf_evals += slots_.size();
            if (mat.uses_network(mode)) counters.network_evals += slots_.size();
            for (std::size_t i = 0; i < slots_.size(); ++i) {
                const float* f = &f_[3 * i];
                // Measured data can be negative (noise) or not finite: no negative light.
                *slots_[i] = Vec3f(max0(f[0]), max0(f[1]), max0(f[2]));
            }
        }
    }

    const Scene& scene_;
    const RenderOptions& opt_;
    std::vector<float> accum_;
    std::vector<Path> paths_;
    std::vector<Shading> shading_;
    std::vector<char> hit_;
    const float cone_spread_;  // the camera cone's spread per unit distance (ray_cone.hpp)
    std::vector<float> wi_, wo_, uv_, f_;
    std::vector<Footprint> footprint_;
    std::vector<Vec3f*> slots_;
    std::vector<DeltaSample> deltas_;  // this bounce's delta-light samples, each path's a range
    std::vector<std::size_t> bucket_, cursor_, order_;  // the counting sort of evaluate()
};

}  // namespace

RenderOptions RenderOptions::from_scene(const RenderSettings& s) {
    RenderOptions o;
    static_cast<RenderSettings&>(o) = s;
    return o;
}

void RenderOptions::validate() const {
    check_settings(*this);
    if (tile_size < 1) throw std::invalid_argument("tile_size: must be >= 1, got " + std::to_string(tile_size));
    if (max_paths_per_wave < 1)
        throw std::invalid_argument("max_paths_per_wave: must be >= 1, got " + std::to_string(max_paths_per_wave));
}

bool use_network(const RenderOptions& options, int depth, const Vec3f& throughput) {
    const int max_d = options.neural_max_depth < 0 ? options.max_depth : options.neural_max_depth;
    return depth < max_d && max_component(throughput) >= options.neural_min_throughput;
}

namespace {

// Runs `worker` on `n` threads and returns how many ran it. Workers share the
// tiles, so when the system refuses a thread the ones started finish the
// image (the same image: it does not depend on the thread count); when it
// refuses all of them, the caller's thread does the work.
template <typename F> int run_workers(F& worker, int n) {
    if (n == 1) {
        worker();  // on the caller's thread: no thread start-up for tiny renders
        return 1;
    }
    std::vector<std::thread> pool;
    pool.reserve(std::size_t(n));
    try {
        for (int i = 0; i < n; ++i) pool.emplace_back(worker);
    } catch (const std::system_error&) {
        if (pool.empty()) worker();
    }
    for (auto& th : pool) th.join();
    return pool.empty() ? 1 : int(pool.size());
}

}  // namespace

std::string film_problem(const Image& image, const Scene& scene) {
    std::uint64_t bad = 0, first = 0;
    for (std::size_t i = 0; i < image.rgb.size(); ++i)
        if (!is_finite(image.rgb[i]) && bad++ == 0) first = i / 3;
    if (bad == 0) return "";
    const std::uint64_t w = std::uint64_t(std::max(image.width, 1));
    std::string problem = "the rendered image holds " + std::to_string(bad) + " values that are not finite (the first at pixel (" +
                          std::to_string(first % w) + ", " + std::to_string(first / w) +
                          ")): the light along its paths overflows float32";
    // Name the lights' brightness, the usual culprit.
    problem += " (the environment's brightest radiance is " + format_number(scene.environment.brightest());
    float brightest_delta = 0.0f;
    for (const PointLight& l : scene.lights.points) brightest_delta = std::max(brightest_delta, max_component(l.intensity));
    for (const DirectionalLight& l : scene.lights.directionals) brightest_delta = std::max(brightest_delta, max_component(l.irradiance));
    if (!scene.lights.empty())
        problem += ", the brightest point or directional light's " + format_number(brightest_delta);
    problem += ")";
    return problem;
}

Image render(const Scene& scene, const RenderOptions& options, RenderStats* stats) {
    options.validate();
    if (scene.materials.empty()) throw std::invalid_argument("the scene has no materials");
    const auto start = std::chrono::steady_clock::now();
    const int W = scene.camera.width(), H = scene.camera.height(), T = options.tile_size;
    Image image(W, H);
    const int tiles_x = (W + T - 1) / T, tiles_y = (H + T - 1) / T, n_tiles = tiles_x * tiles_y;
    int n_threads = options.threads > 0 ? options.threads : int(std::thread::hardware_concurrency());
    n_threads = std::max(1, std::min(n_threads, n_tiles));

    std::atomic<int> next_tile{0};
    std::atomic<bool> abort{false};
    std::exception_ptr error;
    std::mutex error_mutex;
    Counters total;
    std::mutex total_mutex;
    ProgressBar progress(n_tiles, options.quiet);

    auto worker = [&]() {
        TileRenderer tr(scene, options);
        Counters local;
        try {
            for (int t; !abort.load(std::memory_order_relaxed) && (t = next_tile.fetch_add(1)) < n_tiles;) {
                throw_if_cancelled(options.cancel);
                const int x0 = (t % tiles_x) * T, y0 = (t / tiles_x) * T;
                tr.render_tile(x0, y0, std::min(W, x0 + T), std::min(H, y0 + T), image, local);
                progress.tick();
            }
        } catch (...) {
            std::lock_guard<std::mutex> lock(error_mutex);
            if (!error) error = std::current_exception();
            abort = true;
        }
        std::lock_guard<std::mutex> lock(total_mutex);
        total.rays += local.rays;
        total.shadow_rays += local.shadow_rays;
        total.brdf_evals += local.brdf_evals;
        total.network_evals += local.network_evals;
    };
    n_threads = run_workers(worker, n_threads);
    if (error) {
        progress.stop();  // the caller's message goes on a line of its own
        std::rethrow_exception(error);
    }
    progress.finish();
    // Single non-finite samples are dropped (add()), but a sum of finite ones can still overflow.
    if (const std::string problem = film_problem(image, scene); !problem.empty()) throw std::invalid_argument(problem);

    if (stats) {
        stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats->samples_per_second = double(W) * double(H) * double(options.spp) / std::max(stats->seconds, 1e-9);
        stats->rays = total.rays;
        stats->shadow_rays = total.shadow_rays;
        stats->brdf_evals = total.brdf_evals;
        stats->network_evals = total.network_evals;
        stats->threads = n_threads;
        stats->tiles = n_tiles;
    }
    return image;
}

}  // namespace hbrdf::render
