// Evaluates and samples f_a through the installed library; exits non-zero
// if the numbers are not what the formulas give.
#include <cmath>
#include <cstdio>

#include <hybridbrdf/hybridbrdf.hpp>

int main() {
    hbrdf::AnalyticParams p;
    p.kd = {0.f, 0.f, 0.f};
    p.eta = {1.5f, 1.5f, 1.5f};
    p.alpha = {1.f, 1.f};
    const float n[3] = {0.f, 0.f, 1.f};
    float f[3];
    hbrdf::eval_analytic_aos(p, 1, n, n, f);  // F = 0.04, D = 1/pi, G = 1
    const float expected = 0.04f / (4.f * 3.14159265f);
    const hbrdf::BrdfSample s =
        hbrdf::sample(hbrdf::Strategy::Mis, hbrdf::AnalyticBrdf(p), hbrdf::Vec3<float>(0, 0, 1), hbrdf::Vec2<float>(0.3f, 0.6f));
    std::printf("hybridbrdf %s: f = %g (expected %g), sample pdf = %g, simd = %s\n", hbrdf::kVersion, f[0], expected,
                s.pdf, hbrdf::simd_path());
    return (std::abs(f[0] - expected) < 1e-6f * expected && s.pdf > 0.f) ? 0 : 1;
}
