// The generated C++ header's hbrdf_eval over n pairs, in a translation unit of its own: the
// header defines its own hbrdf:: names (float3, ...), which must not meet libhybridbrdf's.
// bench/speed_guard.py compiles it with -include the generated header and
// -DHBRDF_GUARD_MATERIAL=HBRDF_MATERIAL_<NAME>.
#include <cstddef>

void header_eval(std::size_t n, const float* wi, const float* wo, float* f) {
    const hbrdf::HbrdfMaterial mat = hbrdf::HBRDF_GUARD_MATERIAL;
    for (std::size_t i = 0; i < n; ++i) {
        const hbrdf::float3 v = hbrdf::hbrdf_eval(hbrdf::float3(wi[3 * i], wi[3 * i + 1], wi[3 * i + 2]),
                                                  hbrdf::float3(wo[3 * i], wo[3 * i + 1], wo[3 * i + 2]), mat);
        f[3 * i] = v.x;
        f[3 * i + 1] = v.y;
        f[3 * i + 2] = v.z;
    }
}
