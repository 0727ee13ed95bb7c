// hybridbrdf renderer — the JSON scene format (docs/RENDERING.md).
#include "hybridbrdf/render/scene_loader.hpp"
#include "hybridbrdf/render/svbrdf_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cfloat>
#include <climits>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "hybridbrdf/render/gltf_material.hpp"
#include "hybridbrdf/render/integrator.hpp"
#include "hybridbrdf/render/limits.hpp"
#include "hybridbrdf/render/sky.hpp"
#include "scene_reader.hpp"

namespace hbrdf::render {

namespace {

using json = nlohmann::json;
using Reader = detail::SceneReader;

AnalyticParams read_params(const Reader& r, const json& obj, const std::string& where) {
    AnalyticParams p;
    p.kd = r.vec<3>(obj, where, "kd", Vec3f(0.5f), true);
    p.eta = r.vec<3>(obj, where, "eta", Vec3f(1.5f), true);
    p.alpha = r.vec<2>(obj, where, "alpha", Vec2<float>(0.3f), true);
    try {
        validate(p);
    } catch (const std::invalid_argument& e) {
        r.fail(where, e.what());
    }
    return p;
}

// The top-level keys: the scene's parts and every setting of settings.hpp.
void check_top_level(const Reader& r, const json& root) {
    std::vector<std::string> allowed = {"camera", "environment", "materials", "objects"};
    for (const SettingInfo& info : kRenderSettings) allowed.push_back(info.name);
    allowed.push_back("lights");
    allowed.push_back("description");
    r.check_keys(root, "", allowed);
}

// Every row of the settings table, checked by set_setting (no narrowing:
// JSON integers arrive as int64/uint64 and are bounded before conversion).
RenderSettings read_settings(const Reader& r, const json& root) {
    RenderSettings s;
    for (const SettingInfo& info : kRenderSettings) {
        if (!root.contains(info.name)) continue;
        const json& v = root.at(info.name);
        SettingValue value = OtherValue{v.type_name()};
        if (v.is_boolean()) value = v.get<bool>();
        else if (v.is_number_unsigned()) value = v.get<std::uint64_t>();
        else if (v.is_number_integer()) value = v.get<std::int64_t>();
        else if (v.is_number_float()) value = v.get<double>();
        else if (v.is_string()) value = v.get<std::string>();
        const std::string problem = set_setting(s, info, value);
        if (!problem.empty()) r.fail(info.name, problem);
    }
    return s;
}

std::string material_type(const Reader& r, const json& m, const std::string& w) {
    if (!m.is_object()) r.fail(w, "expected an object");
    return r.string(r.require(m, w, "type"), w + ".type");
}

[[noreturn]] void unknown_material_type(const Reader& r, const std::string& w, const std::string& type) {
    r.fail(w + ".type", "unknown material type '" + type + "'; expected analytic, model, measured or textured");
}

AnalyticParams read_analytic(const Reader& r, const json& m, const std::string& w) {
    r.check_keys(m, w, {"type", "kd", "eta", "alpha"});
    return read_params(r, m, w);
}

ModelMaterialDecl read_model_decl(const Reader& r, const json& m, const std::string& w, const std::string& name) {
    r.check_keys(m, w, {"type", "file", "material", "evaluate"});
    ModelMaterialDecl d;
    d.where = w;
    d.name = name;
    d.file = r.resolve(r.string(r.require(m, w, "file"), w + ".file"));
    d.material = r.string(r.require(m, w, "material"), w + ".material");
    const std::string evaluate = m.contains("evaluate") ? r.string(m.at("evaluate"), w + ".evaluate") : "full";
    if (evaluate != "full" && evaluate != "analytic")
        r.fail(w + ".evaluate", "expected 'full' or 'analytic', got '" + evaluate + "'");
    d.analytic_only = evaluate == "analytic";
    return d;
}

struct TexturedDecl {
    std::string folder;  // resolved against the scene's folder
    TexelFilter filter = TexelFilter::Bilinear;
    bool analytic_only = false;
};

// {"type": "textured", "svbrdf": FOLDER, "filter": "bilinear" | "nearest", "evaluate": "full" | "analytic"}
TexturedDecl read_textured_decl(const Reader& r, const json& m, const std::string& w) {
    r.check_keys(m, w, {"type", "svbrdf", "filter", "evaluate"});
    TexturedDecl d;
    d.folder = r.resolve(r.string(r.require(m, w, "svbrdf"), w + ".svbrdf"));
    const std::string filter = m.contains("filter") ? r.string(m.at("filter"), w + ".filter") : "bilinear";
    if (filter != "bilinear" && filter != "nearest")
        r.fail(w + ".filter", "expected 'bilinear' or 'nearest', got '" + filter + "'");
    d.filter = filter == "nearest" ? TexelFilter::Nearest : TexelFilter::Bilinear;
    const std::string evaluate = m.contains("evaluate") ? r.string(m.at("evaluate"), w + ".evaluate") : "full";
    if (evaluate != "full" && evaluate != "analytic")
        r.fail(w + ".evaluate", "expected 'full' or 'analytic', got '" + evaluate + "'");
    d.analytic_only = evaluate == "analytic";
    return d;
}

struct MeasuredDecl {
    std::string source;                  // resolved against the scene's folder
    std::optional<AnalyticParams> proxy;  // "sampling_params"
    bool isotropic = true;
    // A mixture: "layers" (sources, resolved) under the weights map of the painted folder "weights".
    std::vector<std::string> layers;
    std::string weights;
    TexelFilter filter = TexelFilter::Bilinear;
    // What messages call it: the source, or the layers joined by " + ".
    std::string label() const {
        if (layers.empty()) return source;
        std::string s;
        for (const std::string& l : layers) s += (s.empty() ? "" : " + ") + l;
        return s;
    }
};

// {"type": "measured", "source": SOURCE, "sampling_params": {...}, "isotropic": bool}, or the exact
// mixture {"type": "measured", "layers": [SOURCE, ...], "weights": FOLDER, "filter": ..., "isotropic": bool}.
MeasuredDecl read_measured_decl(const Reader& r, const json& m, const std::string& w) {
    r.check_keys(m, w, {"type", "source", "sampling_params", "isotropic", "layers", "weights", "filter"});
    MeasuredDecl d;
    d.isotropic = r.boolean(m, w, "isotropic", true);
    if (m.contains("layers") == m.contains("source"))
        r.fail(w, "a measured material has a 'source', or 'layers' and 'weights' (a mixture), not both or neither");
    if (m.contains("source")) {
        for (const char* key : {"weights", "filter"})
            if (m.contains(key)) r.fail(w + "." + key, "only a mixture ('layers') has it");
        d.source = r.resolve(r.string(m.at("source"), w + ".source"));
        if (m.contains("sampling_params")) {
            const json& sp = m.at("sampling_params");
            r.check_keys(sp, w + ".sampling_params", {"kd", "eta", "alpha"});
            d.proxy = read_params(r, sp, w + ".sampling_params");
        }
        return d;
    }
    if (m.contains("sampling_params"))
        r.fail(w + ".sampling_params", "a mixture samples its weights folder's layers; it takes no sampling_params");
    const json& layers = m.at("layers");
    if (!layers.is_array() || layers.empty() || layers.size() > std::size_t(spec::kSvbrdfMaxLayers))
        r.fail(w + ".layers", "expected an array of 1 to " + std::to_string(spec::kSvbrdfMaxLayers) + " sources");
    for (std::size_t i = 0; i < layers.size(); ++i)
        d.layers.push_back(r.resolve(r.string(layers[i], w + ".layers[" + std::to_string(i) + "]")));
    d.weights = r.resolve(r.string(r.require(m, w, "weights"), w + ".weights"));
    const std::string filter = m.contains("filter") ? r.string(m.at("filter"), w + ".filter") : "bilinear";
    if (filter != "bilinear" && filter != "nearest")
        r.fail(w + ".filter", "expected 'bilinear' or 'nearest', got '" + filter + "'");
    d.filter = filter == "nearest" ? TexelFilter::Nearest : TexelFilter::Bilinear;
    return d;
}

json parse_scene_text(const std::string& json_text, const std::string& origin) {
    json root;
    try {
        root = json::parse(json_text);
    } catch (const json::exception& e) {  // parse_error, and out_of_range for numbers like 1e400
        throw FileError(origin, std::string("invalid JSON: ") + e.what());
    }
    if (!root.is_object()) throw FileError(origin, "expected a JSON object at the top level");
    return root;
}

class Loader {
public:
    Loader(const Reader& r, const SceneLoadOptions& options) : r_(r), options_(options) {}

    Scene load(const json& root) {
        check_top_level(r_, root);
        Scene scene;
        scene.settings = read_settings(r_, root);
        scene.camera = read_camera(r_.require(root, "", "camera"));
        scene.environment = read_environment(root.contains("environment") ? root.at("environment") : json::object());
        if (root.contains("lights")) scene.lights = detail::read_lights(r_, root.at("lights"));
        if (root.contains("materials")) {
            const json& mats = root.at("materials");
            if (!mats.is_object()) r_.fail("materials", "expected an object mapping names to materials");
            for (const auto& item : mats.items()) {
                throw_if_cancelled(options_.cancel);
                named_[item.key()] = scene.add_material(read_material(item.value(), "materials." + item.key(), item.key()));
            }
        }
        const json& objects = r_.require(root, "", "objects");
        if (!objects.is_array() || objects.empty()) r_.fail("objects", "expected a non-empty array");
        for (std::size_t i = 0; i < objects.size(); ++i) {
            throw_if_cancelled(options_.cancel);
            read_object(objects[i], "objects[" + std::to_string(i) + "]", scene);
        }
        // Samplers last: a tabulated one evaluates its material millions of times.
        if (scene.settings.sampler == SamplerKind::Tabulated) {
            for (const auto& mat : scene.materials)
                if (mat->spatially_varying())
                    r_.fail("materials." + mat->name(), "the tabulated sampler tabulates one BRDF; a textured material "
                                                        "samples its texel's layers: use sampler cosine, ggx or mis");
            check_tabulated_budget(scene);
        }
        for (std::size_t m = 0; m < scene.materials.size(); ++m) {
            throw_if_cancelled(options_.cancel);
            try {
                scene.materials[m]->set_sampler(scene.settings.sampler, proxies_[m],
                                                scene.settings.tabulated_resolution_deg, options_.cancel);
            } catch (const std::invalid_argument& e) {
                r_.fail("materials." + scene.materials[m]->name(), e.what());
            }
        }
        throw_if_cancelled(options_.cancel);
        scene.commit();
        return scene;
    }

private:
    // The tables of all materials together against kMaxTabulatedSamplerBytes,
    // before the first is built: each takes seconds and up to 210 MB, so a short
    // scene with many materials would otherwise build for minutes into gigabytes.
    void check_tabulated_budget(const Scene& scene) const {
        const int res = scene.settings.tabulated_resolution_deg;
        const auto need_at = [&scene](int deg, std::size_t& aniso) {
            double bytes = double(TabulatedSampler::build_scratch_bytes(deg));  // one build at a time
            aniso = 0;
            for (const auto& mat : scene.materials) {
                bytes += double(TabulatedSampler::table_bytes(mat->isotropic(), deg));
                aniso += mat->isotropic() ? 0 : 1;
            }
            return bytes;
        };
        std::size_t aniso = 0;
        const double need = need_at(res, aniso);
        if (need <= double(kMaxTabulatedSamplerBytes)) return;
        // The finest coarser resolution that fits, as the advice.
        std::string coarser;
        for (int deg = res + 1; deg <= 90; ++deg) {
            std::size_t unused = 0;
            if (90 % deg == 0 && need_at(deg, unused) <= double(kMaxTabulatedSamplerBytes)) {
                coarser = ", a coarser tabulated_resolution_deg (" + std::to_string(deg) + " fits)";
                break;
            }
        }
        const std::size_t n = scene.materials.size();
        r_.fail("sampler", "the tabulated sampler's tables for " + std::to_string(n) + " material" +
                               (n == 1 ? "" : "s") + " (" + std::to_string(aniso) + " anisotropic) at " +
                               std::to_string(res) + " degree" + (res == 1 ? "" : "s") + " need ~" +
                               format_bytes(need) + ", above the budget of " +
                               format_bytes(double(kMaxTabulatedSamplerBytes)) +
                               " (" + format_number(double(kMaxTabulatedSamplerBytes) / double(1 << 30)) +
                               " GiB) for all of a scene's tables; use fewer materials" + coarser +
                               " or another sampler");
    }

    PinholeCamera read_camera(const json& c) {
        const std::string w = "camera";
        r_.check_keys(c, w, {"position", "look_at", "up", "fov_deg", "width", "height"});
        try {
            return PinholeCamera(r_.vec<3>(r_.require(c, w, "position"), w + ".position"),
                                 r_.vec<3>(r_.require(c, w, "look_at"), w + ".look_at"),
                                 r_.vec<3>(c, w, "up", Vec3f(0, 1, 0)), r_.number(c, w, "fov_deg", 40.0f),
                                 r_.integer(c, w, "width", 256), r_.integer(c, w, "height", 256));
        } catch (const std::invalid_argument& e) {
            r_.fail(w, e.what());
        }
    }

public:
    EnvironmentLight read_environment(const json& e) {
        const std::string w = "environment";
        if (!e.is_object()) r_.fail(w, "expected an object");
        const std::string type = e.contains("type") ? r_.string(e.at("type"), w + ".type") : "sky";
        const float scale = r_.nonnegative(e, w, "scale", 1.0f);
        const float rotation = r_.number(e, w, "rotation_deg", 0.0f);
        if (type == "sky") return light(read_sky(e), scale, rotation);
        if (type == "constant") {
            r_.check_keys(e, w, {"type", "scale", "rotation_deg", "radiance"});
            const Vec3f L = r_.nonnegative_vec<3>(e, w, "radiance", Vec3f(1.0f));
            Image img(8, 4);  // a small image: the same sampling code, sin(theta)-weighted rows
            for (std::size_t i = 0; i < img.rgb.size(); i += 3) {
                img.rgb[i] = L.x;
                img.rgb[i + 1] = L.y;
                img.rgb[i + 2] = L.z;
            }
            return light(std::move(img), scale, rotation);
        }
        if (type == "file") {
            r_.check_keys(e, w, {"type", "scale", "rotation_deg", "file"});
            const std::string file = r_.resolve(r_.string(r_.require(e, w, "file"), w + ".file"));
            Image img;
            try {
                img = read_image(file);  // refuses oversized headers before decoding (limits.hpp)
            } catch (const FileError& ex) {
                r_.fail(w + ".file", ex.what());
            }
            return light(std::move(img), scale, rotation, file);
        }
        r_.fail(w + ".type", "unknown environment type '" + type + "'; expected sky, file or constant");
    }

private:
    // The sky's image; every parameter is checked, with its key, before the
    // image is allocated (a [100000, 50000] resolution is an error, not bad_alloc).
    Image read_sky(const json& e) {
        const std::string w = "environment";
        r_.check_keys(e, w, {"type", "scale", "rotation_deg", "sun_elevation_deg", "sun_azimuth_deg", "sun_irradiance",
                             "sun_size_deg", "sky_intensity", "turbidity", "ground_albedo", "resolution"});
        SkyParams p;
        p.sun_elevation_deg = r_.number(e, w, "sun_elevation_deg", p.sun_elevation_deg);
        p.sun_azimuth_deg = r_.number(e, w, "sun_azimuth_deg", p.sun_azimuth_deg);
        p.sun_irradiance = r_.nonnegative_vec<3>(e, w, "sun_irradiance", p.sun_irradiance);
        p.sun_size_deg = r_.number(e, w, "sun_size_deg", p.sun_size_deg);
        p.sky_intensity = r_.nonnegative(e, w, "sky_intensity", p.sky_intensity);
        p.turbidity = r_.number(e, w, "turbidity", p.turbidity);
        p.ground_albedo = r_.nonnegative_vec<3>(e, w, "ground_albedo", p.ground_albedo);
        const auto res = r_.integers<2>(e, w, "resolution", {p.width, p.height}, 1);
        p.width = res[0];
        p.height = res[1];
        const SkyProblem problem = check_sky(p);
        if (!problem.key.empty()) r_.fail(w + "." + problem.key, problem.problem);
        throw_if_cancelled(options_.cancel);  // a large sky takes seconds to bake
        return make_sky_image(p);
    }

    // `file`: the map's path, named in the message when it is the map's values that are refused.
    EnvironmentLight light(Image img, float scale, float rotation, const std::string& file = "") {
        try {
            return EnvironmentLight(std::move(img), scale, rotation);
        } catch (const std::invalid_argument& ex) {
            r_.fail("environment", file.empty() ? std::string(ex.what()) : file + ": " + ex.what());
        }
    }

    std::unique_ptr<Material> read_material(const json& m, const std::string& w, const std::string& name) {
        const std::string type = material_type(r_, m, w);
        if (type == "analytic") {
            const AnalyticParams p = read_analytic(r_, m, w);
            proxies_.push_back(p);
            return std::make_unique<AnalyticMaterial>(name, p);
        }
        if (type == "model") {
            const ModelMaterialDecl d = read_model_decl(r_, m, w, name);
            std::shared_ptr<const HybridModel>& model = models_[d.file];
            if (!model) {
                try {
                    model = std::make_shared<const HybridModel>(HybridModel::load(d.file));
                } catch (const std::exception& e) {
                    r_.fail(w + ".file", e.what());
                }
            }
            const int index = model->find(d.material);
            if (index < 0) {
                std::string names;
                for (std::size_t i = 0; i < model->materials().size() && i < 8; ++i)
                    names += (i ? ", " : "") + model->materials()[i].name;
                r_.fail(w + ".material", "no material '" + d.material + "' in " + d.file + " (it has " +
                                             std::to_string(model->materials().size()) + ": " + names +
                                             (model->materials().size() > 8 ? ", ..." : "") + ")");
            }
            try {
                auto mm = std::make_unique<ModelMaterial>(name, model, index, d.analytic_only);
                proxies_.push_back(mm->analytic_params());
                return mm;
            } catch (const std::invalid_argument& e) {
                r_.fail(w, e.what());
            }
        }
        if (type == "textured") {
            const TexturedDecl d = read_textured_decl(r_, m, w);
            auto tm = std::make_unique<TexturedMaterial>(name, svbrdf(d.folder, w + ".svbrdf"), d.filter, d.analytic_only);
            proxies_.push_back(tm->base_params());  // records the strategy; sampling reads the texel's layers
            return tm;
        }
        if (type == "measured") {
            MeasuredDecl d = read_measured_decl(r_, m, w);
            if (!options_.measured)
                r_.fail(w, "measured materials ('" + d.label() +
                               "') are evaluated by Python readers: render this scene with hybridbrdf.render.tracer "
                               "or 'hbrdf render'");
            auto open = [&](const std::string& source, const std::string& where) {
                try {
                    return naming_errors(options_.measured(source), w);
                } catch (const Cancelled&) {
                    throw;
                } catch (const std::exception& e) {
                    r_.fail(where, e.what());
                }
            };
            if (d.layers.empty()) {
                proxies_.push_back(d.proxy);
                return std::make_unique<CallbackMaterial>(name, open(d.source, w + ".source"), d.isotropic);
            }
            const std::shared_ptr<const Svbrdf> sv = svbrdf(d.weights, w + ".weights");
            if (int(d.layers.size()) != sv->layer_count())
                r_.fail(w + ".layers", std::to_string(d.layers.size()) + " sources for the " +
                                           std::to_string(sv->layer_count()) + " layers of '" + d.weights + "'");
            std::vector<BatchEval> evals;
            for (std::size_t i = 0; i < d.layers.size(); ++i)
                evals.push_back(open(d.layers[i], w + ".layers[" + std::to_string(i) + "]"));
            auto mm = std::make_unique<MeasuredMixtureMaterial>(name, std::move(evals), sv, d.filter, d.isotropic);
            proxies_.push_back(mm->base_params());  // records the strategy; sampling reads the texel's layers
            return mm;
        }
        unknown_material_type(r_, w, type);
    }

    // A painted folder, read once per scene however many materials name it.
    std::shared_ptr<const Svbrdf> svbrdf(const std::string& folder, const std::string& where) {
        std::shared_ptr<const Svbrdf>& sv = svbrdfs_[folder];
        if (!sv) {
            try {
                sv = load_svbrdf(folder);
            } catch (const std::exception& e) {
                r_.fail(where, e.what());
            }
        }
        return sv;
    }

    // A measured callback whose failures (while rendering, or while a
    // tabulated sampler is built) name the scene and the material's key.
    BatchEval naming_errors(BatchEval eval, const std::string& where) const {
        const std::string prefix = r_.origin() + ": " + where + ": ";
        return [eval = std::move(eval), prefix](std::size_t n, const float* wi, const float* wo, float* f) {
            try {
                eval(n, wi, wo, f);
            } catch (const Cancelled&) {
                throw;
            } catch (const std::exception& e) {
                throw MaterialError(prefix + e.what());
            }
        };
    }

    int material_of(const json& obj, const std::string& w, Scene& scene) {
        const json& m = r_.require(obj, w, "material");
        if (m.is_string()) {
            const auto it = named_.find(m.get<std::string>());
            if (it == named_.end()) r_.fail(w + ".material", "no material named '" + m.get<std::string>() + "' in 'materials'");
            return it->second;
        }
        // Inline material, named after the object.
        return scene.add_material(read_material(m, w + ".material", w));
    }

    void read_object(const json& o, const std::string& w, Scene& scene) {
        if (!o.is_object()) r_.fail(w, "expected an object");
        const std::string type = r_.string(r_.require(o, w, "type"), w + ".type");
        if (type == "sphere") {
            r_.check_keys(o, w, {"type", "material", "center", "radius"});
            Sphere s;
            s.center = r_.vec<3>(o, w, "center", Vec3f(0.0f));
            s.radius = r_.number(o, w, "radius", 1.0f);
            if (!(s.radius > 0.0f)) r_.fail(w + ".radius", "must be > 0");
            add_geometry(w, [&] { scene.add_sphere(s, material_of(o, w, scene)); });
        } else if (type == "plane") {
            r_.check_keys(o, w, {"type", "material", "center", "normal", "tangent", "size"});
            const Vec3f n = r_.vec<3>(o, w, "normal", Vec3f(0, 1, 0));
            if (!(dot(n, n) > 0.0f)) r_.fail(w + ".normal", "must not be zero");
            const Vec3f t = r_.vec<3>(o, w, "tangent", Frame::from_normal(glm::normalize(n)).t);
            const Vec2<float> size = r_.vec<2>(o, w, "size", Vec2<float>(10.0f), true);
            if (!(size.x > 0.0f && size.y > 0.0f)) r_.fail(w + ".size", "must be > 0");
            const Vec3f center = r_.vec<3>(o, w, "center", Vec3f(0.0f));
            add_geometry(w, [&] { scene.add_mesh(make_plane(center, n, t, size.x, size.y), material_of(o, w, scene)); });
        } else if (type == "mesh") {
            r_.check_keys(o, w, {"type", "material", "file", "transform", "smooth_normals"});
            const std::string file = r_.resolve(r_.string(r_.require(o, w, "file"), w + ".file"));
            TriangleMesh mesh;
            try {
                mesh = load_mesh(file, r_.boolean(o, w, "smooth_normals", true));
            } catch (const FileError& e) {
                r_.fail(w + ".file", e.what());
            }
            if (o.contains("transform")) {
                transform_mesh(mesh, read_transform(o.at("transform"), w + ".transform"));
                if (const std::int64_t v = first_nonfinite_vertex(mesh); v >= 0)
                    r_.fail(w + ".transform", "moves vertex " + std::to_string(v) + " beyond the float range");
            }
            add_geometry(w, [&] { scene.add_mesh(std::move(mesh), material_of(o, w, scene)); });
        } else if (type == "gltf") {
            read_gltf_object(o, w, scene);
        } else {
            r_.fail(w + ".type", "unknown object type '" + type + "'; expected sphere, plane, mesh or gltf");
        }
    }

    // {"type": "gltf", "file", "transform", "bind": {glTF material name: scene material name |
    // "MODEL#MATERIAL" | textured folder}}: every triangle of the asset, its node transforms applied,
    // then the object's transform; each part with its glTF material as an f_a, or the bound one.
    void read_gltf_object(const json& o, const std::string& w, Scene& scene) {
        r_.check_keys(o, w, {"type", "file", "transform", "bind"});
        const std::string file = r_.resolve(r_.string(r_.require(o, w, "file"), w + ".file"));
        detail::GltfAsset asset;
        try {
            asset = detail::read_gltf(file);
        } catch (const FileError& e) {
            r_.fail(w + ".file", e.what());
        }
        const json none = json::object();
        const json& bind = o.contains("bind") ? o.at("bind") : none;
        if (!bind.is_object()) r_.fail(w + ".bind", "expected an object mapping glTF material names to materials");
        for (const auto& item : bind.items()) {
            const bool known = std::any_of(asset.materials.begin(), asset.materials.end(),
                                           [&](const detail::GltfFa& m) { return m.name == item.key(); });
            if (!known) r_.fail(w + ".bind." + item.key(), "the asset has no material named '" + item.key() + "'" + gltf_names(asset));
        }
        std::map<int, int> material_of_part;  // glTF material index (-1: default) -> scene material
        auto scene_material = [&](int g) {
            if (const auto it = material_of_part.find(g); it != material_of_part.end()) return it->second;
            detail::GltfFa fa;
            if (g >= 0) fa = asset.materials[std::size_t(g)];
            else fa = detail::gltf_material_to_fa(r_, none, w);  // glTF's default material
            const std::string label = w + ":" + (g < 0 ? std::string("default") : fa.name.empty() ? "#" + std::to_string(g) : fa.name);
            int index;
            if (g >= 0 && !fa.name.empty() && bind.contains(fa.name)) {
                index = bound_material(bind.at(fa.name), w + ".bind." + fa.name, label, scene);
                // The asset's normal map stays, unless the bound folder brings its own (docs/GLTF.md).
                const auto* folder = dynamic_cast<const TexturedMaterial*>(scene.materials[std::size_t(index)].get());
                if (fa.normal && !(folder && folder->svbrdf().has_normal_map())) {
                    const std::optional<AnalyticParams> proxy = proxies_[std::size_t(index)];
                    proxies_.push_back(proxy);
                    index = scene.add_material(std::make_unique<NormalMappedMaterial>(label, scene.materials[std::size_t(index)].get(), *fa.normal));
                }
            } else if (fa.textured()) {  // per-texel f_a of its factors times its textures
                auto gm = std::make_unique<GltfMaterial>(label, fa.factors, fa.base_color, fa.metallic_roughness, fa.normal);
                proxies_.push_back(gm->factor_params());  // records the strategy; sampling reads the texel's f_a
                index = scene.add_material(std::move(gm));
            } else {
                proxies_.push_back(fa.params);
                index = scene.add_material(std::make_unique<AnalyticMaterial>(label, fa.params));
            }
            return material_of_part[g] = index;
        };
        std::optional<Transform> xf;
        if (o.contains("transform")) xf = read_transform(o.at("transform"), w + ".transform");
        for (detail::GltfPart& part : asset.parts) {
            const int g = part.material;
            const bool bound = g >= 0 && bind.contains(asset.materials[std::size_t(g)].name);
            // The tangent turns by anisotropyRotation where the glTF material renders as itself.
            if (g >= 0 && !bound) detail::rotate_tangents(part.mesh, asset.materials[std::size_t(g)].rotation);
            if (xf) {
                transform_mesh(part.mesh, *xf);
                if (const std::int64_t v = first_nonfinite_vertex(part.mesh); v >= 0)
                    r_.fail(w + ".transform", "moves vertex " + std::to_string(v) + " beyond the float range");
            }
            const int material = scene_material(g);
            add_geometry(w, [&] { scene.add_mesh(std::move(part.mesh), material); });
        }
    }

    // A bind's target: a scene material's name, "MODEL_FILE#MATERIAL", or a textured folder.
    int bound_material(const json& target, const std::string& w, const std::string& label, Scene& scene) {
        const std::string t = r_.string(target, w);
        if (const auto it = named_.find(t); it != named_.end()) return it->second;
        const auto hash = t.rfind('#');
        const json m = hash != std::string::npos ? json{{"type", "model"}, {"file", t.substr(0, hash)}, {"material", t.substr(hash + 1)}}
                                                 : json{{"type", "textured"}, {"svbrdf", t}};
        return scene.add_material(read_material(m, w, label));
    }

    static std::string gltf_names(const detail::GltfAsset& asset) {
        std::string names;
        for (const detail::GltfFa& m : asset.materials)
            if (!m.name.empty()) names += (names.empty() ? "" : ", ") + ("'" + m.name + "'");
        return names.empty() ? " (its materials have no names)" : " (it has " + names + ")";
    }

    // Scene::add_* refuses geometry Embree cannot use (non-finite vertices,
    // indices out of range): the error names the object.
    template <typename F> void add_geometry(const std::string& w, F&& add) {
        try {
            add();
        } catch (const std::invalid_argument& e) {
            r_.fail(w, e.what());
        }
    }

    // scale (number or [3]), then rotate (degrees about x, then y, then z), then translate.
    Transform read_transform(const json& t, const std::string& w) {
        r_.check_keys(t, w, {"translate", "scale", "rotate_deg"});
        const Vec3f s = r_.vec<3>(t, w, "scale", Vec3f(1.0f), true);
        const Vec3f rdeg = r_.vec<3>(t, w, "rotate_deg", Vec3f(0.0f));
        if (s.x == 0.0f || s.y == 0.0f || s.z == 0.0f) r_.fail(w + ".scale", "must not be zero");
        auto rot = [](int axis, float deg) {
            const float a = deg * 3.14159265358979323846f / 180.0f, c = std::cos(a), sn = std::sin(a);
            glm::mat3 m(1.0f);  // column-major: m[col][row]
            const int i = (axis + 1) % 3, j = (axis + 2) % 3;
            m[i][i] = c;
            m[j][j] = c;
            m[i][j] = sn;
            m[j][i] = -sn;
            return m;
        };
        Transform xf;
        xf.linear = rot(2, rdeg.z) * rot(1, rdeg.y) * rot(0, rdeg.x) * glm::mat3(glm::vec3(s.x, 0, 0), glm::vec3(0, s.y, 0), glm::vec3(0, 0, s.z));
        xf.translation = r_.vec<3>(t, w, "translate", Vec3f(0.0f));
        return xf;
    }

    const Reader& r_;
    const SceneLoadOptions& options_;
    std::map<std::string, int> named_;
    std::map<std::string, std::shared_ptr<const HybridModel>> models_;
    std::vector<std::optional<AnalyticParams>> proxies_;  // by material index
    std::map<std::string, std::shared_ptr<const Svbrdf>> svbrdfs_;  // by folder: read once
};

}  // namespace

Scene load_scene_json(const std::string& json_text, const std::string& base_dir, const std::string& origin,
                      const SceneLoadOptions& options) {
    const json root = parse_scene_text(json_text, origin);
    const Reader reader(origin, base_dir);
    return Loader(reader, options).load(root);
}

EnvironmentLight load_environment_json(const std::string& json_text, const std::string& base_dir,
                                       const std::string& origin, const SceneLoadOptions& options) {
    const json root = parse_scene_text(json_text, origin);
    const Reader reader(origin, base_dir);
    return Loader(reader, options).read_environment(root);
}

SceneDecl read_scene_decl(const std::string& json_text, const std::string& base_dir, const std::string& origin) {
    const json root = parse_scene_text(json_text, origin);
    const Reader r(origin, base_dir);
    check_top_level(r, root);
    SceneDecl decl;
    decl.settings = read_settings(r, root);
    // Each material through the readers load_scene uses, without the loading.
    auto declare = [&](const json& m, const std::string& w, const std::string& name) {
        const std::string type = material_type(r, m, w);
        if (type == "analytic") read_analytic(r, m, w);
        else if (type == "model") decl.model_materials.push_back(read_model_decl(r, m, w, name));
        else if (type == "measured") read_measured_decl(r, m, w);
        else if (type == "textured") decl.textured_folders.push_back(read_textured_decl(r, m, w).folder);
        else unknown_material_type(r, w, type);
        if (type != "model") decl.other_materials.push_back({w, name, type});
    };
    std::set<std::string> named;
    if (root.contains("materials")) {
        const json& mats = root.at("materials");
        if (!mats.is_object()) r.fail("materials", "expected an object mapping names to materials");
        for (const auto& item : mats.items()) {
            declare(item.value(), "materials." + item.key(), item.key());
            named.insert(item.key());
        }
    }
    const json& objects = r.require(root, "", "objects");
    if (!objects.is_array() || objects.empty()) r.fail("objects", "expected a non-empty array");
    for (std::size_t i = 0; i < objects.size(); ++i) {
        const std::string w = "objects[" + std::to_string(i) + "]";
        if (!objects[i].is_object()) r.fail(w, "expected an object");
        if (objects[i].contains("type") && objects[i].at("type") == "gltf") {
            // The asset's own materials are f_a (known once the file is read); its binds name scene
            // materials, "MODEL#MATERIAL" or textured folders.
            const json& bind = objects[i].contains("bind") ? objects[i].at("bind") : json::object();
            if (!bind.is_object()) r.fail(w + ".bind", "expected an object mapping glTF material names to materials");
            for (const auto& item : bind.items()) {
                const std::string wb = w + ".bind." + item.key(), t = r.string(item.value(), wb);
                if (named.count(t)) continue;
                const auto hash = t.rfind('#');
                if (hash != std::string::npos)
                    declare(json{{"type", "model"}, {"file", t.substr(0, hash)}, {"material", t.substr(hash + 1)}}, wb, wb);
                else declare(json{{"type", "textured"}, {"svbrdf", t}}, wb, wb);
            }
            continue;
        }
        const json& m = r.require(objects[i], w, "material");
        if (!m.is_string()) declare(m, w + ".material", w);
        else if (!named.count(m.get<std::string>()))
            r.fail(w + ".material", "no material named '" + m.get<std::string>() + "' in 'materials'");
    }
    return decl;
}

Scene load_scene(const std::string& path, const SceneLoadOptions& options) {
    check_input_file(path, "scene file");  // a FIFO would block the open below
    std::ifstream in(path);
    if (!in) throw FileError(path, "cannot open the scene file");
    std::stringstream ss;
    ss << in.rdbuf();
    const auto slash = path.find_last_of('/');
    const std::string base = slash == std::string::npos ? "." : path.substr(0, slash);
    return load_scene_json(ss.str(), base, path, options);
}

}  // namespace hbrdf::render
