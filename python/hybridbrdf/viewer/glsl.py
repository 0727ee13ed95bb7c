"""The WebGL2 shaders of ``hbrdf view``'s page (docs/VIEWER.md, "The shader" and "Lighting"): the
fragment shader that adds one sample of each pixel's radiance to its running sums, GLSL ES 3.00
made of ``hbrdf-codegen --target glsl`` output unchanged and the page's own ``main``; and the display
pass. hybridbrdf.viewer.wgsl is the same for WebGPU.
"""

from __future__ import annotations

#: GLSL ES 3.00 in front of the generated GLSL: WebGL2 takes the version only on the first line.
ES_PREFIX = "#version 300 es\nprecision highp float;\nprecision highp int;\n"

#: The page's own shader code after the generated GLSL: the material from uniforms, the camera ray,
#: the sphere in the tracer's frame, and one frame's samples of the pixel's radiance added to the
#: sums so far (u_accum; rgb = sum of radiance, a = number of samples). Two lights:
#: - u_light 0, the sun alone: a direction, f cos E at the pixel's centre, one exact sample;
#: - u_light 1, the environment map: direct light by Monte Carlo, each sample one direction from the
#:   map (in proportion to luminance x sin(theta), as the tracer) and one from hbrdf_sample, combined
#:   by the power heuristic (Veach 1997), at a jittered point of the pixel (the tracer's box filter).
_MAIN = """
// ---- hbrdf view: one unit sphere at the origin (docs/VIEWER.md) ----
uniform vec3 u_kd;
uniform vec3 u_eta;
uniform vec2 u_alpha;
uniform vec4 u_pack[{n_vec}];
uniform bool u_analytic;
uniform int u_light;
uniform vec3 u_sun;
uniform float u_irradiance;
uniform highp sampler2D u_env;              // RGBA32F: radiance, and the texel's density over (u, v)
uniform highp sampler2D u_env_marginal;     // R32F, (H + 1) x 1: the rows' CDF
uniform highp sampler2D u_env_conditional;  // R32F, (W + 1) x H: each row's CDF over its texels
uniform ivec2 u_env_size;
uniform vec2 u_env_rotation;                // cos, sin of the map's rotation_deg about +y
uniform highp sampler2D u_accum;
uniform uint u_sample;
uniform vec3 u_cam_pos, u_cam_fwd, u_cam_right, u_cam_up;
uniform vec2 u_tan;
uniform vec2 u_size;
out vec4 frag_color;

const float HBRDF_VIEW_PI = 3.14159265358979;
// The largest float below 1: u = 1 would index one texel past the map.
const float HBRDF_VIEW_ONE_MINUS_EPS = 0.99999994;

float hbrdf_view_packed(int i) {{ return u_pack[i / 4][i % 4]; }}
HbrdfMaterial hbrdf_view_material() {{
    HbrdfMaterial m;
    m.kd = u_kd;
    m.eta = u_eta;
    m.alpha_x = u_alpha.x;
    m.alpha_y = u_alpha.y;
    for (int i = 0; i < {z_len}; ++i) m.z[i] = hbrdf_view_packed(i);
{head_lines}    return m;
}}
// Random numbers: a Kronecker (Weyl) sequence in 6 dimensions, its steps the powers of 1 / g with
// g^7 = g + 1 (Roberts 2018), in 32-bit fixed point so that sample 10^5 is as exact as sample 1,
// shifted per pixel by a hash (Cranley-Patterson rotation): low discrepancy within a pixel,
// independent between pixels.
uint hbrdf_view_hash(uint x) {{
    x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
    return x;
}}
float hbrdf_view_unit(uint x) {{ return float(x >> 8) * (1.0 / 16777216.0); }}
void hbrdf_view_random(uvec2 pixel, uint index, out vec4 u, out vec2 jitter) {{
    uint h = hbrdf_view_hash(pixel.x * 0x9e3779b9u ^ hbrdf_view_hash(pixel.y + 0x632be5abu));
    u = vec4(hbrdf_view_unit(index * 0xe6ab68f2u + h), hbrdf_view_unit(index * 0xcef33b7fu + hbrdf_view_hash(h + 1u)),
             hbrdf_view_unit(index * 0xba44a09bu + hbrdf_view_hash(h + 2u)),
             hbrdf_view_unit(index * 0xa92dd2afu + hbrdf_view_hash(h + 3u)));
    jitter = vec2(hbrdf_view_unit(index * 0x9a8c3a5du + hbrdf_view_hash(h + 4u)),
                  hbrdf_view_unit(index * 0x8c1e4b51u + hbrdf_view_hash(h + 5u)));
}}

// The tracer's equirect mapping (EnvironmentLight): theta from +y, phi = atan2(x, -z) in the map's
// frame, which is the world turned by -rotation about +y.
vec2 hbrdf_view_env_uv(vec3 d) {{
    float mx = u_env_rotation.x * d.x - u_env_rotation.y * d.z;
    float mz = u_env_rotation.y * d.x + u_env_rotation.x * d.z;
    float theta = acos(clamp(d.y, -1.0, 1.0));
    float phi = atan(mx, -mz);
    phi = phi < 0.0 ? phi + 2.0 * HBRDF_VIEW_PI : phi;
    return min(vec2(phi / (2.0 * HBRDF_VIEW_PI), theta / HBRDF_VIEW_PI), vec2(HBRDF_VIEW_ONE_MINUS_EPS));
}}
vec3 hbrdf_view_env_direction(vec2 uv) {{
    float theta = uv.y * HBRDF_VIEW_PI, phi = uv.x * 2.0 * HBRDF_VIEW_PI;
    float s = sin(theta);
    float mx = s * sin(phi), my = cos(theta), mz = -s * cos(phi);
    return vec3(u_env_rotation.x * mx + u_env_rotation.y * mz, my, -u_env_rotation.y * mx + u_env_rotation.x * mz);
}}
vec4 hbrdf_view_env_texel(vec2 uv) {{
    return texelFetch(u_env, min(ivec2(uv * vec2(u_env_size)), u_env_size - 1), 0);
}}
// Solid-angle density of a map sample toward d (d omega = 2 pi^2 sin(theta) du dv); sin(theta)
// from x and z, which does not cancel near the poles as sqrt(1 - y^2) does.
float hbrdf_view_env_pdf(vec3 d, vec4 texel) {{
    float sin_theta = sqrt(d.x * d.x + d.z * d.z);
    return sin_theta > 0.0 ? texel.a / (2.0 * HBRDF_VIEW_PI * HBRDF_VIEW_PI * sin_theta) : 0.0;
}}
// The bin of a piecewise-constant distribution for u in [0, 1): the largest i < n with cdf[i] <= u
// (bins of zero probability are never chosen), and where u falls inside it.
float hbrdf_view_invert_cdf(highp sampler2D cdf, int row, int n, float u) {{
    int lo = 0, hi = n;  // cdf[lo] <= u < cdf[hi] = 1
    while (lo + 1 < hi) {{
        int mid = (lo + hi) / 2;
        if (texelFetch(cdf, ivec2(mid, row), 0).r <= u) lo = mid; else hi = mid;
    }}
    float c0 = texelFetch(cdf, ivec2(lo, row), 0).r, c1 = texelFetch(cdf, ivec2(lo + 1, row), 0).r;
    float du = c1 > c0 ? clamp((u - c0) / (c1 - c0), 0.0, 1.0) : 0.5;
    return min((float(lo) + du) / float(n), HBRDF_VIEW_ONE_MINUS_EPS);
}}
vec3 hbrdf_view_env_sample(vec2 u, out vec4 texel, out float pdf) {{
    float v = hbrdf_view_invert_cdf(u_env_marginal, 0, u_env_size.y, u.y);
    int row = min(int(v * float(u_env_size.y)), u_env_size.y - 1);
    float uu = hbrdf_view_invert_cdf(u_env_conditional, row, u_env_size.x, u.x);
    vec3 d = hbrdf_view_env_direction(vec2(uu, v));
    texel = hbrdf_view_env_texel(vec2(uu, v));
    pdf = hbrdf_view_env_pdf(d, texel);
    return d;
}}
// The directions of one sample of the reflected radiance toward wo (local frame tg, bt, n), each
// with the factor its f(wi, wo) cos(theta_i) is multiplied by: a map sample and a BRDF sample, each
// weighted by the power heuristic (w / p = p / (p^2 + q^2)); the sun alone: its direction and E.
// Returns how many there are. The BRDF is evaluated in one place (hbrdf_view_radiance's loop):
// every call site of hbrdf_eval is a copy of the network in the compiled shader, and a software
// WebGL compiles each (SwiftShader: seconds per copy at 32x2).
int hbrdf_view_directions(vec3 wo, vec3 tg, vec3 bt, vec3 n, HbrdfMaterial m, vec4 u, out vec3 wi0, out vec3 weight0,
                          out vec3 wi1, out vec3 weight1) {{
    if (u_light == 0) {{
        wi0 = vec3(dot(u_sun, tg), dot(u_sun, bt), dot(u_sun, n));
        weight0 = vec3(u_irradiance);
        wi1 = weight1 = vec3(0.0);
        return 1;
    }}
    vec4 texel;
    float p_light;
    vec3 d = hbrdf_view_env_sample(u.xy, texel, p_light);
    wi0 = vec3(dot(d, tg), dot(d, bt), dot(d, n));
    float p_brdf = hbrdf_pdf(wi0, wo, m);
    weight0 = p_light > 0.0 ? texel.rgb * (p_light / (p_light * p_light + p_brdf * p_brdf)) : vec3(0.0);
    wi1 = hbrdf_sample(wo, u.zw, m, p_brdf);
    d = wi1.x * tg + wi1.y * bt + wi1.z * n;
    texel = hbrdf_view_env_texel(hbrdf_view_env_uv(d));
    p_light = hbrdf_view_env_pdf(d, texel);
    weight1 = p_brdf > 0.0 ? texel.rgb * (p_brdf / (p_brdf * p_brdf + p_light * p_light)) : vec3(0.0);
    return 2;
}}
// Radiance through the film point p (pixels, y down) from the tracer's pinhole (docs/RENDERING.md).
vec3 hbrdf_view_radiance(vec2 p, vec4 u) {{
    float sx = (2.0 * p.x / u_size.x - 1.0) * u_tan.x;
    float sy = (1.0 - 2.0 * p.y / u_size.y) * u_tan.y;
    vec3 d = normalize(u_cam_fwd + u_cam_right * sx + u_cam_up * sy);
    vec3 o = u_cam_pos;
    float b = dot(o, d), disc = b * b - (dot(o, o) - 1.0);
    // A ray that misses the sphere sees the map behind it, as the tracer's camera rays do (the sun
    // alone is a black sky: its disc is not drawn).
    if (disc <= 0.0) return u_light == 1 ? hbrdf_view_env_texel(hbrdf_view_env_uv(d)).rgb : vec3(0.0);
    vec3 n = normalize(o + (-b - sqrt(disc)) * d);
    // The tracer's sphere frame: tangent d p / d phi about +y (the alpha_x axis).
    vec3 tg = vec3(-n.z, 0.0, n.x);
    float len2 = dot(tg, tg);
    tg = len2 > 1e-12 ? tg / sqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 bt = cross(n, tg);
    vec3 wo = vec3(dot(-d, tg), dot(-d, bt), dot(-d, n));
    if (wo.z <= 0.0) return vec3(0.0);
    HbrdfMaterial m = hbrdf_view_material();
    vec3 wi0, weight0, wi1, weight1;
    int count = hbrdf_view_directions(wo, tg, bt, n, m, u, wi0, weight0, wi1, weight1);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < count; ++k) {{
        vec3 wi = k == 0 ? wi0 : wi1, weight = k == 0 ? weight0 : weight1;
        if (wi.z > 0.0 && any(greaterThan(weight, vec3(0.0)))) {{
            sum += max(u_analytic ? hbrdf_eval_analytic(wi, wo, m) : hbrdf_eval(wi, wo, m), vec3(0.0)) * wi.z * weight;
        }}
    }}
    return sum;
}}
// One sample per pixel per draw: a loop over samples around the loop over directions makes
// SwiftShader's compile of the 32x2 network take 15 s instead of 1 (measured); the page draws again
// for more samples.
void main() {{
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec2 film = vec2(gl_FragCoord.x, u_size.y - gl_FragCoord.y);  // pixel (0, 0) top left, y down
    vec4 u;
    vec2 jitter;
    hbrdf_view_random(uvec2(px), u_sample, u, jitter);
    // The sun alone is one sample at the pixel's centre; the map's are spread over the pixel.
    vec2 p = u_light == 1 ? floor(film) + jitter : film;
    frag_color = texelFetch(u_accum, px, 0) + vec4(hbrdf_view_radiance(p, u), 1.0);
}}
"""

#: The page's second pass: the mean of the sums, 2^exposure x, clipped to [0, 1], the sRGB OETF
#: (8 bits in the canvas): what ``hbrdf render --png --tonemap clamp`` writes.
DISPLAY_SHADER = """#version 300 es
precision highp float;
uniform highp sampler2D u_accum;
uniform float u_gain;
out vec4 frag_color;
float hbrdf_view_srgb(float x) {
    x = clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}
void main() {
    vec4 acc = texelFetch(u_accum, ivec2(gl_FragCoord.xy), 0);
    vec3 c = (acc.a > 0.0 ? acc.rgb / acc.a : vec3(0.0)) * u_gain;
    frag_color = vec4(hbrdf_view_srgb(c.r), hbrdf_view_srgb(c.g), hbrdf_view_srgb(c.b), 1.0);
}
"""


def fragment_shader(glsl: str, z_len: int, n_pack: int, head_w: int = 0, n_out: int = 0, energy: int = 0) -> str:
    """The page's fragment shader (GLSL ES 3.00): :data:`ES_PREFIX`, ``glsl`` (``hbrdf-codegen --target
    glsl`` output, unchanged) and the page's ``main``. ``head_w``/``n_out``: the material output
    layer's sizes (0 for a shared one); ``energy``: the energy-bound table's length (0 for none); the
    packed uniforms hold z, then head_w, then head_b, then the table."""
    head_lines = ""
    if head_w:
        head_lines = (f"    for (int i = 0; i < {head_w}; ++i) m.head_w[i] = hbrdf_view_packed({z_len} + i);\n"
                      f"    for (int i = 0; i < {n_out}; ++i) m.head_b[i] = hbrdf_view_packed({z_len + head_w} + i);\n")
    if energy:
        at = z_len + (head_w + n_out if head_w else 0)
        head_lines += f"    for (int i = 0; i < {energy}; ++i) m.energy[i] = hbrdf_view_packed({at} + i);\n"
    return ES_PREFIX + glsl + _MAIN.format(n_vec=(n_pack + 3) // 4, z_len=z_len, head_lines=head_lines)


__all__ = ["DISPLAY_SHADER", "ES_PREFIX", "fragment_shader"]
