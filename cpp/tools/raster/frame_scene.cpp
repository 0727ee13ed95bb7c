// hbrdf_raster — a tracer scene as a raster frame's arrays (frame_scene.hpp).
#include "frame_scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "hybridbrdf/render/material.hpp"

namespace hbrdf::raster {
namespace {

constexpr double kPi = 3.14159265358979323846;

using render::Vec3f;

// The distance from the origin to the closest point of triangle abc (Ericson, Real-Time Collision
// Detection 5.1.5, by region tests on the barycentrics), in double.
double origin_distance(const double a[3], const double b[3], const double c[3]) {
    auto sub = [](const double* x, const double* y, double* r) { for (int i = 0; i < 3; ++i) r[i] = x[i] - y[i]; };
    auto dot = [](const double* x, const double* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    const double p[3] = {0, 0, 0};
    sub(b, a, ab), sub(c, a, ac), sub(p, a, ap);
    double q[3];
    auto at = [&](double v, double w) { for (int i = 0; i < 3; ++i) q[i] = a[i] + ab[i] * v + ac[i] * w; return std::sqrt(dot(q, q)); };
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return at(0, 0);
    sub(p, b, bp);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return at(1, 0);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return at(d1 / (d1 - d3), 0);
    sub(p, c, cp);
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return at(0, 1);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return at(0, d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at(1 - w, w);
    }
    const double denom = 1 / (va + vb + vc);
    return at(vb * denom, vc * denom);
}

// A unit sphere's point at grid vertex (i over phi, j over theta), as the tracer parametrises it:
// theta from the +y pole, phi = atan2(z, x) in (-pi, pi].
void unit_sphere_point(int i, int j, int n_phi, int n_theta, double out[3]) {
    const double phi = -kPi + 2 * kPi * i / n_phi, theta = kPi * j / n_theta;
    out[0] = std::sin(theta) * std::cos(phi);
    out[1] = std::cos(theta);
    out[2] = std::sin(theta) * std::sin(phi);
}

// Appends sphere s's grid; returns the largest gap between its triangles and the sphere.
double add_sphere(const render::Sphere& s, int n_phi, FrameScene& out) {
    const int n_theta = n_phi / 2;
    const uint32_t base = uint32_t(out.vertices.size());
    for (int j = 0; j <= n_theta; ++j)
        for (int i = 0; i <= n_phi; ++i) {
            double n[3];
            unit_sphere_point(i, j, n_phi, n_theta, n);
            const double phi = -kPi + 2 * kPi * i / n_phi;
            Vertex v{};
            for (int k = 0; k < 3; ++k) {
                v.p[k] = float(double(s.center[k]) + double(s.radius) * n[k]);
                v.n[k] = float(n[k]);
            }
            // d p / d phi = sin(theta) (-sin phi, 0, cos phi), here unit (also at the poles, where
            // the tracer takes any frame): interpolation sees the same direction along a meridian.
            v.t[0] = float(-std::sin(phi));
            v.t[2] = float(std::cos(phi));
            v.uv[0] = float(double(i) / n_phi);  // phi / 2 pi + 1/2
            v.uv[1] = float(double(j) / n_theta);
            out.vertices.push_back(v);
        }
    double gap = 0;
    const auto index = [&](int i, int j) { return base + uint32_t(j * (n_phi + 1) + i); };
    for (int j = 0; j < n_theta; ++j)
        for (int i = 0; i < n_phi; ++i) {
            const uint32_t a = index(i, j), b = index(i + 1, j), c = index(i, j + 1), d = index(i + 1, j + 1);
            if (j > 0) out.indices.insert(out.indices.end(), {a, c, b});           // none at the +y pole
            if (j + 1 < n_theta) out.indices.insert(out.indices.end(), {b, c, d});  // none at the -y pole
            if (i == 0) {  // the grid is the same in every phi column: measure one column
                double pa[3], pb[3], pc[3], pd[3];
                unit_sphere_point(i, j, n_phi, n_theta, pa), unit_sphere_point(i + 1, j, n_phi, n_theta, pb);
                unit_sphere_point(i, j + 1, n_phi, n_theta, pc), unit_sphere_point(i + 1, j + 1, n_phi, n_theta, pd);
                if (j > 0) gap = std::max(gap, 1 - origin_distance(pa, pc, pb));
                if (j + 1 < n_theta) gap = std::max(gap, 1 - origin_distance(pb, pc, pd));
            }
        }
    return gap * double(s.radius);
}

void add_mesh(const render::TriangleMesh& m, FrameScene& out) {
    const uint32_t base = uint32_t(out.vertices.size());
    for (std::size_t k = 0; k < m.positions.size(); ++k) {
        Vertex v{};
        for (int c = 0; c < 3; ++c) {
            v.p[c] = m.positions[k][c];
            v.n[c] = m.normals.empty() ? 0.0f : m.normals[k][c];
            v.t[c] = m.tangents.empty() ? 0.0f : m.tangents[k][c];
        }
        if (!m.uvs.empty()) v.uv[0] = m.uvs[k][0], v.uv[1] = m.uvs[k][1];
        v.w = m.tangent_signs.empty() ? 1.0f : float(m.tangent_signs[k]);
        out.vertices.push_back(v);
    }
    for (uint32_t i : m.indices) out.indices.push_back(base + i);
}

GpuMaterial analytic_entry(const AnalyticParams& p, int kind) {
    GpuMaterial g{};
    for (int c = 0; c < 3; ++c) g.kd[c] = p.kd[c], g.eta[c] = p.eta[c];
    g.alpha[0] = p.alpha.x, g.alpha[1] = p.alpha.y;
    g.kind[0] = kind;
    g.kind[1] = g.kind[2] = g.kind[3] = -1;
    return g;
}

// The next slot of `textures`, holding t (or -1 without one).
int32_t slot(const std::optional<render::GltfTexture>& t, std::vector<render::GltfTexture>& textures) {
    if (!t) return -1;
    textures.push_back(*t);
    return int32_t(textures.size()) - 1;
}

// The table entry of scene material m; kind -1 where the raster frame cannot draw it.
GpuMaterial material_entry(const render::Material& m, const std::vector<std::string>& model_materials,
                           std::vector<render::GltfTexture>& textures) {
    const auto listed = std::find(model_materials.begin(), model_materials.end(), m.name());
    const int model_case = listed == model_materials.end() ? -1 : int(listed - model_materials.begin()) + 1;
    if (const auto* a = dynamic_cast<const render::AnalyticMaterial*>(&m)) return analytic_entry(a->params(), 0);
    if (const auto* gm = dynamic_cast<const render::GltfMaterial*>(&m)) {
        const render::GltfFactors& k = gm->factors();
        GpuMaterial g{};
        for (int c = 0; c < 3; ++c) g.kd[c] = float(k.base[c]), g.eta[c] = float(k.dielectric_f0[c]);
        g.alpha[0] = float(k.metallic), g.alpha[1] = float(k.roughness), g.alpha[2] = float(k.anisotropy);
        g.kind[0] = kGltfCase;
        g.kind[1] = slot(gm->base_color(), textures);
        g.kind[2] = slot(gm->metallic_roughness(), textures);
        g.kind[3] = slot(gm->normal() ? std::optional<render::GltfTexture>(gm->normal()->texture) : std::nullopt, textures);
        g.alpha[3] = gm->normal() ? float(gm->normal()->scale) : 1.0f;
        return g;
    }
    if (const auto* nm = dynamic_cast<const render::NormalMappedMaterial*>(&m)) {  // a bound material, the asset's normal map
        GpuMaterial g = material_entry(nm->inner(), model_materials, textures);
        if (g.kind[0] == -1) return g;
        g.kind[3] = slot(nm->normal().texture, textures);
        g.alpha[3] = float(nm->normal().scale);
        return g;
    }
    if (const auto* t = dynamic_cast<const render::TexturedMaterial*>(&m); t && model_case > 0)
        return analytic_entry(t->base_params(), model_case);  // the shader reads its maps
    if (const auto* model = dynamic_cast<const render::ModelMaterial*>(&m)) {
        const std::optional<AnalyticParams> p = model->analytic_params();
        if (model_case > 0) return analytic_entry(p.value_or(AnalyticParams{}), model_case);
        if (p) return analytic_entry(*p, 0);
    }
    GpuMaterial g{};
    g.kind[0] = -1;
    return g;
}

void push_light(std::vector<float>& lights, const Vec3f& a, const Vec3f& b) {
    lights.insert(lights.end(), {a.x, a.y, a.z, 0.0f, b.x, b.y, b.z, 0.0f});
}

// view_proj maps world p to clip space so that pixel (x + 1/2, y + 1/2) sees what
// PinholeCamera::generate(x + 1/2, y + 1/2) sees: x_ndc = s_x / (tan_half aspect), y_ndc = -s_y /
// tan_half with s = (right.d, up.d) / forward.d, d = p - position. Depth is reversed and infinite:
// z_clip = near, w_clip = forward.d, so depth = near / distance along the view axis (1 at the near
// plane, toward 0 far away; float depth keeps its precision there).
void camera_uniform(const render::PinholeCamera& cam, float out[20]) {
    const double th = cam.tan_half_fov(), aspect = double(cam.width()) / double(cam.height());
    const double near = 1e-3 * cam.distance();
    const Vec3f &o = cam.position(), &r = cam.right(), &u = cam.up(), &f = cam.forward();
    double rows[4][4] = {};
    const double sx = 1 / (th * aspect), sy = -1 / th;
    for (int k = 0; k < 3; ++k) rows[0][k] = sx * r[k], rows[1][k] = sy * u[k], rows[3][k] = f[k];
    rows[0][3] = -sx * (double(r.x) * o.x + double(r.y) * o.y + double(r.z) * o.z);
    rows[1][3] = -sy * (double(u.x) * o.x + double(u.y) * o.y + double(u.z) * o.z);
    rows[2][3] = near;
    rows[3][3] = -(double(f.x) * o.x + double(f.y) * o.y + double(f.z) * o.z);
    for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 4; ++row) out[col * 4 + row] = float(rows[row][col]);
    out[16] = o.x, out[17] = o.y, out[18] = o.z, out[19] = 1.0f;
}

}  // namespace

FrameScene build_frame_scene(const render::Scene& scene, const std::vector<std::string>& model_materials,
                             int sphere_segments) {
    if (sphere_segments < 8 || sphere_segments > 8192 || sphere_segments % 2)
        throw std::invalid_argument("sphere segments must be an even number in [8, 8192], got " +
                                    std::to_string(sphere_segments));
    FrameScene out;
    for (const auto& m : scene.materials) out.materials.push_back(material_entry(*m, model_materials, out.gltf_textures));
    for (const std::string& name : model_materials)
        if (std::none_of(scene.materials.begin(), scene.materials.end(), [&](const auto& m) { return m->name() == name; }))
            throw std::invalid_argument("--model-material '" + name + "' is no material of the scene");
    auto draw = [&](int material, auto&& add) {
        if (out.materials.at(std::size_t(material)).kind[0] == -1)
            throw std::invalid_argument("material '" + scene.materials[std::size_t(material)]->name() + "' (" +
                                        scene.materials[std::size_t(material)]->type() +
                                        "): the raster frame draws analytic, model and textured materials only (a textured one as a "
                                        "--model-material, its maps given as --texture)");
        Draw d;
        d.first_index = uint32_t(out.indices.size());
        d.material = material;
        add();
        d.index_count = uint32_t(out.indices.size()) - d.first_index;
        out.draws.push_back(d);
    };
    for (std::size_t i = 0; i < scene.mesh_count(); ++i)
        draw(scene.mesh_material(i), [&] { add_mesh(scene.mesh(i), out); });
    for (std::size_t i = 0; i < scene.sphere_count(); ++i)
        draw(scene.sphere_material(i), [&] {
            out.max_sphere_gap = std::max(out.max_sphere_gap, add_sphere(scene.sphere(i), sphere_segments, out));
        });
    const render::DeltaLights& l = scene.lights;
    out.lights = {0, 0, 0, 0};
    const uint32_t counts[2] = {uint32_t(l.points.size()), uint32_t(l.directionals.size())};
    std::memcpy(out.lights.data(), counts, sizeof counts);
    for (const auto& p : l.points) push_light(out.lights, p.position, p.intensity);
    for (const auto& d : l.directionals) push_light(out.lights, d.direction, d.irradiance);
    if (l.empty()) out.lights.resize(out.lights.size() + 8, 0.0f);  // a buffer's array holds at least one light
    camera_uniform(scene.camera, out.camera);
    return out;
}

}  // namespace hbrdf::raster
