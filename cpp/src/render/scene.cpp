// hybridbrdf renderer — Embree 3 geometry: triangle meshes and analytic spheres.
#include "hybridbrdf/render/scene.hpp"

#include "hybridbrdf/render/limits.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace hbrdf::render {

namespace {

void check_device(RTCDevice device, const char* what) {
    const RTCError err = rtcGetDeviceError(device);
    if (err != RTC_ERROR_NONE) throw std::runtime_error(std::string("Embree error ") + std::to_string(int(err)) + " in " + what);
}

// ---- the analytic sphere as Embree user geometry ----------------------------

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
    const auto* s = static_cast<const Sphere*>(args->geometryUserPtr);
    RTCBounds* b = args->bounds_o;
    b->lower_x = s->center.x - s->radius;
    b->lower_y = s->center.y - s->radius;
    b->lower_z = s->center.z - s->radius;
    b->upper_x = s->center.x + s->radius;
    b->upper_y = s->center.y + s->radius;
    b->upper_z = s->center.z + s->radius;
}

// Roots of |o + t d - c|^2 = r^2 in double, in the form that avoids both
// catastrophic cancellations (the discriminant from the perpendicular
// distance, Haines et al., Ray Tracing Gems ch. 7; the near root from the
// product of roots). Returns false when the ray misses.
bool sphere_roots(const Sphere& s, const double o[3], const double d[3], double* t0, double* t1) {
    const double f[3] = {o[0] - s.center.x, o[1] - s.center.y, o[2] - s.center.z};
    const double a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double b = -(f[0] * d[0] + f[1] * d[1] + f[2] * d[2]);  // -f.d
    const double r = s.radius;
    const double c = f[0] * f[0] + f[1] * f[1] + f[2] * f[2] - r * r;
    const double l[3] = {f[0] + b / a * d[0], f[1] + b / a * d[1], f[2] + b / a * d[2]};
    const double disc = a * (r * r - (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]));
    if (!(disc >= 0.0)) return false;
    const double q = b + std::copysign(std::sqrt(disc), b);
    const double ta = c / q, tb = q / a;
    *t0 = std::min(ta, tb);
    *t1 = std::max(ta, tb);
    return std::isfinite(*t0) && std::isfinite(*t1);
}

void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
    const auto* s = static_cast<const Sphere*>(args->geometryUserPtr);
    RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
    RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, args->N);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const double o[3] = {RTCRayN_org_x(rays, args->N, i), RTCRayN_org_y(rays, args->N, i), RTCRayN_org_z(rays, args->N, i)};
        const double d[3] = {RTCRayN_dir_x(rays, args->N, i), RTCRayN_dir_y(rays, args->N, i), RTCRayN_dir_z(rays, args->N, i)};
        double t0, t1;
        if (!sphere_roots(*s, o, d, &t0, &t1)) continue;
        const double tnear = RTCRayN_tnear(rays, args->N, i);
        float& tfar = RTCRayN_tfar(rays, args->N, i);
        const double t = t0 > tnear ? t0 : t1;
        if (!(t > tnear && t < double(tfar))) continue;
        tfar = float(t);
        RTCHitN_Ng_x(hits, args->N, i) = float(o[0] + t * d[0] - s->center.x);
        RTCHitN_Ng_y(hits, args->N, i) = float(o[1] + t * d[1] - s->center.y);
        RTCHitN_Ng_z(hits, args->N, i) = float(o[2] + t * d[2] - s->center.z);
        RTCHitN_u(hits, args->N, i) = 0.0f;
        RTCHitN_v(hits, args->N, i) = 0.0f;
        RTCHitN_primID(hits, args->N, i) = args->primID;
        RTCHitN_geomID(hits, args->N, i) = args->geomID;
        RTCHitN_instID(hits, args->N, i, 0) = args->context->instID[0];
    }
}

void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
    const auto* s = static_cast<const Sphere*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const double o[3] = {RTCRayN_org_x(args->ray, args->N, i), RTCRayN_org_y(args->ray, args->N, i), RTCRayN_org_z(args->ray, args->N, i)};
        const double d[3] = {RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i), RTCRayN_dir_z(args->ray, args->N, i)};
        double t0, t1;
        if (!sphere_roots(*s, o, d, &t0, &t1)) continue;
        const double tnear = RTCRayN_tnear(args->ray, args->N, i);
        float& tfar = RTCRayN_tfar(args->ray, args->N, i);
        const double t = t0 > tnear ? t0 : t1;
        if (t > tnear && t < double(tfar)) tfar = -std::numeric_limits<float>::infinity();  // Embree's "occluded"
    }
}

RTCRay make_ray(const Vec3f& o, const Vec3f& d, float t_max) {
    RTCRay ray{};
    ray.org_x = o.x;
    ray.org_y = o.y;
    ray.org_z = o.z;
    ray.dir_x = d.x;
    ray.dir_y = d.y;
    ray.dir_z = d.z;
    ray.tnear = 0.0f;
    ray.tfar = t_max;
    ray.mask = 0xFFFFFFFFu;
    ray.flags = 0;
    ray.time = 0.0f;
    return ray;
}

// v / |v|, also where |v|^2 overflows float (the cross product of a triangle's edges longer than
// ~4e9: the geometric normal became 0 and a plane of size 3e10 rendered black) or underflows.
Vec3f normalized(const Vec3f& v) {
    const float inv = inverse_length_or_zero(v);
    if (inv > 0.0f) return v * inv;
    const float m = std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    if (!(m > 0.0f) || !is_finite(m)) return Vec3f(0.0f);
    const Vec3f u = v / m;  // largest component +-1: its squared length is in [1, 3]
    return u * inverse_length_or_zero(u);
}

bool all_finite(const Vec3f& v) { return is_finite(v.x) && is_finite(v.y) && is_finite(v.z); }

std::string point_name(const std::string& what, const Vec3f& p) {
    return what + " (" + format_number(p.x) + ", " + format_number(p.y) + ", " + format_number(p.z) + ")";
}

// What Embree and intersect() rely on: finite vertices within the float32 limits of the camera's
// scale (limits.hpp, check_extent), whole triangles,
// indices in range (an out-of-range index would read past the vertex buffer),
// per-vertex normals and tangents for every vertex when present.
void check_mesh(const TriangleMesh& m, double camera_distance) {
    if (m.indices.empty() || m.indices.size() % 3 != 0)
        throw std::invalid_argument("the mesh has " + std::to_string(m.indices.size()) + " indices, expected 3 per triangle");
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        const Vec3f& p = m.positions[i];
        if (!all_finite(p)) throw std::invalid_argument("vertex " + std::to_string(i) + " is not finite");
        const double extent = std::max({std::fabs(double(p.x)), std::fabs(double(p.y)), std::fabs(double(p.z))});
        const std::string problem = check_extent(point_name("vertex " + std::to_string(i), p), extent, camera_distance);
        if (!problem.empty()) throw std::invalid_argument(problem);
    }
    for (std::size_t i = 0; i < m.indices.size(); ++i)
        if (m.indices[i] >= m.positions.size())
            throw std::invalid_argument("triangle " + std::to_string(i / 3) + " refers to vertex " +
                                        std::to_string(m.indices[i]) + ", but the mesh has " +
                                        std::to_string(m.positions.size()) + " vertices");
    if (!m.normals.empty() && m.normals.size() != m.positions.size())
        throw std::invalid_argument("the mesh has " + std::to_string(m.normals.size()) + " normals for " +
                                    std::to_string(m.positions.size()) + " vertices");
    if (!m.uvs.empty() && m.uvs.size() != m.positions.size())
        throw std::invalid_argument("the mesh has " + std::to_string(m.uvs.size()) + " uvs for " +
                                    std::to_string(m.positions.size()) + " vertices");
    if (!m.tangents.empty() && m.tangents.size() != m.positions.size())
        throw std::invalid_argument("the mesh has " + std::to_string(m.tangents.size()) + " tangents for " +
                                    std::to_string(m.positions.size()) + " vertices");
    if (!m.tangent_signs.empty() && m.tangent_signs.size() != m.positions.size())
        throw std::invalid_argument("the mesh has " + std::to_string(m.tangent_signs.size()) + " tangent signs for " +
                                    std::to_string(m.positions.size()) + " vertices");
}

}  // namespace

Scene::Scene() {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("cannot create the Embree device");
    scene_ = rtcNewScene(device_);
    // Robust mode: watertight triangle tests, so paths do not leak through
    // shared mesh edges (a reference renderer would rather be right than fast).
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
}

Scene::~Scene() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

Scene::Scene(Scene&& o) noexcept { *this = std::move(o); }

Scene& Scene::operator=(Scene&& o) noexcept {
    if (this != &o) {
        std::swap(device_, o.device_);
        std::swap(scene_, o.scene_);
        std::swap(geometries_, o.geometries_);
        std::swap(meshes_, o.meshes_);
        std::swap(spheres_, o.spheres_);
        std::swap(committed_, o.committed_);
        std::swap(materials, o.materials);
        std::swap(environment, o.environment);
        std::swap(lights, o.lights);
        std::swap(camera, o.camera);
        std::swap(settings, o.settings);
    }
    return *this;
}

int Scene::add_material(std::unique_ptr<Material> material) {
    materials.push_back(std::move(material));
    return int(materials.size()) - 1;
}

void Scene::add_mesh(TriangleMesh mesh, int material) {
    if (committed_) throw std::logic_error("Scene::add_mesh after commit()");
    check_mesh(mesh, camera.distance());
    meshes_.push_back(std::make_unique<TriangleMesh>(std::move(mesh)));
    const TriangleMesh& m = *meshes_.back();
    RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), m.positions.size()));
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        v[3 * i] = m.positions[i].x;
        v[3 * i + 1] = m.positions[i].y;
        v[3 * i + 2] = m.positions[i].z;
    }
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), m.triangle_count()));
    std::copy(m.indices.begin(), m.indices.end(), idx);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(scene_, geom, unsigned(geometries_.size()));
    rtcReleaseGeometry(geom);
    check_device(device_, "add_mesh");
    geometries_.push_back({false, int(meshes_.size()) - 1, material});
}

void Scene::add_sphere(const Sphere& sphere, int material) {
    if (committed_) throw std::logic_error("Scene::add_sphere after commit()");
    if (!(sphere.radius > 0.0f)) throw std::invalid_argument("sphere radius must be > 0");
    // Its bounds (center +- radius) must be finite floats for Embree.
    if (!all_finite(sphere.center - Vec3f(sphere.radius)) || !all_finite(sphere.center + Vec3f(sphere.radius)))
        throw std::invalid_argument("the sphere's bounds (center +- radius) overflow float");
    const double extent = double(sphere.radius) + std::max({std::fabs(double(sphere.center.x)), std::fabs(double(sphere.center.y)),
                                                            std::fabs(double(sphere.center.z))});
    const std::string problem = check_extent("the sphere (center " + point_name("", sphere.center).substr(1) +
                                                 ", radius " + format_number(sphere.radius) + ")",
                                             extent, camera.distance());
    if (!problem.empty()) throw std::invalid_argument(problem);
    spheres_.push_back(std::make_unique<Sphere>(sphere));
    RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geom, 1);
    rtcSetGeometryUserData(geom, spheres_.back().get());
    rtcSetGeometryBoundsFunction(geom, sphere_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geom, sphere_intersect);
    rtcSetGeometryOccludedFunction(geom, sphere_occluded);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(scene_, geom, unsigned(geometries_.size()));
    rtcReleaseGeometry(geom);
    check_device(device_, "add_sphere");
    geometries_.push_back({true, int(spheres_.size()) - 1, material});
}

int Scene::mesh_material(std::size_t i) const {
    for (const Geometry& g : geometries_)
        if (!g.is_sphere && std::size_t(g.index) == i) return g.material;
    throw std::out_of_range("Scene::mesh_material: no mesh " + std::to_string(i));
}

int Scene::sphere_material(std::size_t i) const {
    for (const Geometry& g : geometries_)
        if (g.is_sphere && std::size_t(g.index) == i) return g.material;
    throw std::out_of_range("Scene::sphere_material: no sphere " + std::to_string(i));
}

void Scene::commit() {
    rtcCommitScene(scene_);
    check_device(device_, "commit");
    committed_ = true;
}

bool Scene::intersect(const Vec3f& origin, const Vec3f& dir, SurfaceHit* hit, float t_max) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray = make_ray(origin, dir, t_max);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;

    const Geometry& g = geometries_[rh.hit.geomID];
    Vec3f ng, ns, tangent(0.0f);
    bool mirrored = false;  // b = -(n x t): a mirrored uv island (glTF TANGENT.w = -1)
    hit->t = rh.ray.tfar;
    if (g.is_sphere) {
        const Sphere& s = *spheres_[std::size_t(g.index)];
        const Vec3f n = normalized(origin + dir * rh.ray.tfar - s.center);
        hit->p = s.center + n * s.radius;  // reprojected onto the surface
        ng = ns = n;
        tangent = Vec3f(-n.z, 0.0f, n.x);  // d p / d phi about +y
        const float phi = std::atan2(n.z, n.x);  // increases along the tangent
        hit->uv = Vec2<float>(phi * (0.5f * kInvPi<float>) + 0.5f, std::acos(std::clamp(n.y, -1.0f, 1.0f)) * kInvPi<float>);
        hit->uv_scale_log2 = sphere_uv_scale_log2(s.radius, std::sqrt(std::max(0.0f, 1.0f - n.y * n.y)));
        sphere_uv_gradients(n, s.radius, &hit->du_dp, &hit->dv_dp);
    } else {
        const TriangleMesh& m = *meshes_[std::size_t(g.index)];
        const std::uint32_t* tri = &m.indices[3 * std::size_t(rh.hit.primID)];
        const float u = rh.hit.u, v = rh.hit.v, w = 1.0f - u - v;
        const Vec3f &p0 = m.positions[tri[0]], &p1 = m.positions[tri[1]], &p2 = m.positions[tri[2]];
        hit->p = p0 * w + p1 * u + p2 * v;
        ng = normalized(glm::cross(p1 - p0, p2 - p0));
        ns = m.normals.empty() ? ng : normalized(m.normals[tri[0]] * w + m.normals[tri[1]] * u + m.normals[tri[2]] * v);
        if (!(dot(ns, ns) > 0.0f)) ns = ng;
        if (!m.tangents.empty()) tangent = m.tangents[tri[0]] * w + m.tangents[tri[1]] * u + m.tangents[tri[2]] * v;
        // Valid assets give a triangle's three vertices one sign; otherwise its first vertex's
        // decides (Vulkan's provoking vertex: the raster frame's flat attribute).
        if (!m.tangent_signs.empty()) mirrored = m.tangent_signs[tri[0]] < 0;
        if (m.uvs.empty()) {
            hit->uv = Vec2<float>(0.0f);
            hit->uv_scale_log2 = kPointFootprint;
            hit->du_dp = hit->dv_dp = Vec3f(0.0f);
        } else {
            const Vec2<float> &t0 = m.uvs[tri[0]], &t1 = m.uvs[tri[1]], &t2 = m.uvs[tri[2]];
            hit->uv = t0 * w + t1 * u + t2 * v;
            hit->uv_scale_log2 = triangle_uv_scale_log2(p0, p1, p2, t0, t1, t2);
            triangle_uv_gradients(p0, p1, p2, t0, t1, t2, &hit->du_dp, &hit->dv_dp);
        }
        if (dot(ns, ng) < 0.0f) ns = -ns;  // files whose winding disagrees with their normals
    }
    if (dot(ng, dir) > 0.0f) {  // hit from behind: surfaces are two-sided
        ng = -ng;
        ns = -ns;
    }
    hit->ng = ng;
    hit->shading = Frame::from_normal_tangent(ns, tangent);
    if (mirrored) hit->shading.b = -hit->shading.b;  // the tangent space glTF defines, left-handed there
    hit->material = g.material;
    return true;
}

bool Scene::occluded(const Vec3f& origin, const Vec3f& dir, float t_max) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray = make_ray(origin, dir, t_max);
    rtcOccluded1(scene_, &context, &ray);
    return ray.tfar < 0.0f;
}

Vec3f Scene::offset_origin(const SurfaceHit& hit, const Vec3f& dir) {
    const float scale = 1.0f + std::max({std::fabs(hit.p.x), std::fabs(hit.p.y), std::fabs(hit.p.z)});
    const float eps = 2e-5f * scale;
    return hit.p + hit.ng * (dot(hit.ng, dir) > 0.0f ? eps : -eps);
}

}  // namespace hbrdf::render
