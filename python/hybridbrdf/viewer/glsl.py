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

{material}// Random numbers: a Kronecker (Weyl) sequence in 6 dimensions, its steps the powers of 1 / g with
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
int hbrdf_view_directions(vec3 wo, vec3 tg, vec3 bt, vec3 n, HbrdfViewShading m, vec4 u, out vec3 wi0, out vec3 weight0,
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
    float p_brdf = hbrdf_view_pdf(wi0, wo, m);
    weight0 = p_light > 0.0 ? texel.rgb * (p_light / (p_light * p_light + p_brdf * p_brdf)) : vec3(0.0);
    wi1 = hbrdf_view_sample(wo, u.zw, m, p_brdf);
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
    HbrdfViewShading m = hbrdf_view_shading(n, p);
    vec3 wi0, weight0, wi1, weight1;
    int count = hbrdf_view_directions(wo, tg, bt, n, m, u, wi0, weight0, wi1, weight1);
    return hbrdf_view_reflected(wo, m, count, wi0, weight0, wi1, weight1);
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

#: The material of a page of one material: uniforms, so that the picker and the sliders never
#: recompile. ``hbrdf_view_pdf``, ``hbrdf_view_sample`` and ``hbrdf_view_reflected`` are the
#: generated functions of that one material.
_UNIFORM_MATERIAL = """uniform vec3 u_kd;
uniform vec3 u_eta;
uniform vec2 u_alpha;
uniform vec4 u_pack[{n_vec}];
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
#define HbrdfViewShading HbrdfMaterial
HbrdfMaterial hbrdf_view_shading(vec3 n, vec2 p) {{ return hbrdf_view_material(); }}
float hbrdf_view_pdf(vec3 wi, vec3 wo, HbrdfMaterial m) {{ return hbrdf_pdf(wi, wo, m); }}
vec3 hbrdf_view_sample(vec3 wo, vec2 u, HbrdfMaterial m, out float pdf) {{ return hbrdf_sample(wo, u, m, pdf); }}
// One call site of the network (a loop over the sample's directions).
vec3 hbrdf_view_reflected(vec3 wo, HbrdfMaterial m, int count, vec3 wi0, vec3 weight0, vec3 wi1, vec3 weight1) {{
    vec3 sum = vec3(0.0);
    for (int k = 0; k < count; ++k) {{
        vec3 wi = k == 0 ? wi0 : wi1, weight = k == 0 ? weight0 : weight1;
        if (wi.z > 0.0 && any(greaterThan(weight, vec3(0.0)))) {{
            sum += max(u_analytic ? hbrdf_eval_analytic(wi, wo, m) : hbrdf_eval(wi, wo, m), vec3(0.0)) * wi.z * weight;
        }}
    }}
    return sum;
}}
"""

#: The material of a page of a textured material (``hbrdf view --svbrdf``, docs/VIEWER.md "A textured
#: material"): up to 4 layers, each a material of the model (uniform arrays, packed as above) whose
#: kd, eta, alpha and latent code a map may replace, mixed by the weights map. The maps are the
#: decoded values (what hybridbrdf.load_svbrdf returns), float32, one RGBA32F layer of u_maps per
#: map file, so the shader applies no decode; filtered as the runtimes filter them (decode, then
#: filter): bilinear over the four nearest texel centres, repeat or clamp, at the tracer's sphere uv
#: (u = phi / 2 pi + 1/2 with phi = atan2(n.z, n.x), v = theta / pi from +y). The texel's f is
#: hbrdf_eval_layers' sum, 0 + f_0 w_0 + f_1 w_1 + ..., in that order over the layers of positive
#: weight, written as a loop so that the network has one call site (hbrdf_eval_layers has four, and
#: SwiftShader compiles each copy for seconds); its sampling and density are hbrdf_sample_layers' and
#: hbrdf_pdf_layers' arithmetic (the tracer's mixture of the layers' samplers) written as loops over a
#: layer index. The shading point keeps only what the maps change (kd, eta, alpha, z per layer); a
#: layer's HbrdfMaterial is built where one is used, its output layer and energy table read from the
#: uniforms by the layer's index: four HbrdfMaterials passed by value (each with its output layer and
#: table, 118 floats for a 16x2 model) were most of the shader SwiftShader compiled. A normal map (one
#: more plane, x and y) gives the texel its shading frame (libhybridbrdf's normal_map.hpp): the
#: directions stay in the sphere's frame (the cosine is its normal's) and the layers see them in the
#: shading frame, f = 0 unless both are above both horizons; sampled in it and returned.
_TEXTURED_MATERIAL = """uniform vec3 u_layer_kd[4];
uniform vec3 u_layer_eta[4];
uniform vec2 u_layer_alpha[4];
uniform vec4 u_layer_pack[{n_layer_vec}];
uniform int u_layers;                    // 1 to 4
uniform highp sampler2DArray u_maps;     // RGBA32F, W x H, one layer per map file: decoded values
uniform ivec2 u_map_size;
uniform bool u_map_repeat;               // addressing: repeat, else clamp
uniform int u_plane_weights;             // the weights map's layer of u_maps (w_1, w_2, w_3), -1: none
uniform ivec4 u_plane_kd, u_plane_eta, u_plane_alpha, u_plane_latent;  // per material layer; -1: its material's
uniform int u_plane_normal;              // the normal map's layer of u_maps (x, y), -1: none
uniform int u_map_levels;                // 1, or the mip chain's levels (u_maps' own mip levels)
// The texel's layers as the maps make them (layer k's latent code: z[k * {z_len} ...]) and weights.
struct HbrdfViewShading {{
    vec3 kd[4];
    vec3 eta[4];
    vec2 alpha[4];
    float z[4 * {z_len}];
    vec4 w;
    vec2 nxy;         // the normal map's filtered x, y
    vec3 ts, bs, ns;  // the normal map's shading frame in the sphere's (tg, bt, n) coordinates
}};
// A direction of the sphere's frame in the shading frame's coordinates.
vec3 hbrdf_view_to_shading(HbrdfViewShading s, vec3 w) {{ return vec3(dot(w, s.ts), dot(w, s.bs), dot(w, s.ns)); }}
// The normal map's rule (docs/SVBRDF.md): f = 0 unless wi and wo are above both horizons.
bool hbrdf_view_above(HbrdfViewShading s, vec3 wi, vec3 wo) {{
    return wi.z > 0.0 && wo.z > 0.0 && dot(wi, s.ns) > 0.0 && dot(wo, s.ns) > 0.0;
}}
float hbrdf_view_packed(int k, int i) {{ return u_layer_pack[k * {n_vec} + i / 4][i % 4]; }}
int hbrdf_view_wrap(int i, int n) {{
    return u_map_repeat ? (i < 0 ? i + n : (i >= n ? i - n : i)) : clamp(i, 0, n - 1);
}}
// Bilinear filter of one map at uv, as a + (b - a) t: a constant map gives its value exactly, as
// the runtimes' double-precision taps do.
vec4 hbrdf_view_map(int plane, vec2 uv, int level) {{
    ivec2 size = max(u_map_size >> level, ivec2(1));
    vec2 t = u_map_repeat ? fract(uv) : clamp(uv, 0.0, 1.0);
    vec2 x = t * vec2(size) - 0.5;
    vec2 x0 = floor(x);
    vec2 f = x - x0;
    int i0 = hbrdf_view_wrap(int(x0.x), size.x), i1 = hbrdf_view_wrap(int(x0.x) + 1, size.x);
    int j0 = hbrdf_view_wrap(int(x0.y), size.y), j1 = hbrdf_view_wrap(int(x0.y) + 1, size.y);
    vec4 a = texelFetch(u_maps, ivec3(i0, j0, plane), level), b = texelFetch(u_maps, ivec3(i1, j0, plane), level);
    vec4 c = texelFetch(u_maps, ivec3(i0, j1, plane), level), d = texelFetch(u_maps, ivec3(i1, j1, plane), level);
    vec4 top = a + (b - a) * f.x, bottom = c + (d - c) * f.x;
    return top + (bottom - top) * f.y;
}}
// Layer k's mapped values at uv into s (a layer beyond the last has weight 0: any valid material,
// the last layer's).
void hbrdf_view_layer(int k, vec2 uv, int level, inout HbrdfViewShading s) {{
    int kk = min(k, u_layers - 1);
    s.kd[k] = u_plane_kd[kk] >= 0 ? hbrdf_view_map(u_plane_kd[kk], uv, level).rgb : u_layer_kd[kk];
    s.eta[k] = u_plane_eta[kk] >= 0 ? hbrdf_view_map(u_plane_eta[kk], uv, level).rgb : u_layer_eta[kk];
    s.alpha[k] = u_plane_alpha[kk] >= 0 ? hbrdf_view_map(u_plane_alpha[kk], uv, level).rg : u_layer_alpha[kk];
    for (int p = 0; p < ({z_len} + 2) / 3; ++p) {{  // one lookup per latent map (3 components)
        vec4 v = u_plane_latent[kk] >= 0 ? hbrdf_view_map(u_plane_latent[kk] + p, uv, level) : vec4(0.0);
        for (int c = 0; c < 3; ++c) {{
            int i = 3 * p + c;
            if (i < {z_len}) s.z[k * {z_len} + i] = u_plane_latent[kk] >= 0 ? v[c] : hbrdf_view_packed(kk, i);
        }}
    }}
}}
// Layer k's HbrdfMaterial without its output layer and energy table, which hbrdf_pdf and
// hbrdf_sample do not read (ANGLE zero-fills them).
HbrdfMaterial hbrdf_view_material(HbrdfViewShading s, int k) {{
    HbrdfMaterial m;
    m.kd = s.kd[k];
    m.eta = s.eta[k];
    m.alpha_x = s.alpha[k].x;
    m.alpha_y = s.alpha[k].y;
    for (int i = 0; i < {z_len}; ++i) m.z[i] = s.z[k * {z_len} + i];
    return m;
}}
// Layer k's whole HbrdfMaterial, for hbrdf_eval: the output layer and energy table from the uniforms.
HbrdfMaterial hbrdf_view_material_full(HbrdfViewShading s, int k) {{
    int kk = min(k, u_layers - 1);
    HbrdfMaterial m = hbrdf_view_material(s, k);
{layer_head_lines}    return m;
}}
// The texel's weights as libhybridbrdf's Svbrdf::texel normalises them: w_1..3 filtered, divided by
// their sum where it exceeds 1, w_0 = 1 - their sum clamped to [0, 1].
vec4 hbrdf_view_weights(vec2 uv, int level) {{
    if (u_plane_weights < 0) return vec4(1.0, 0.0, 0.0, 0.0);
    vec3 r = hbrdf_view_map(u_plane_weights, uv, level).rgb;
    r = vec3(r.x, u_layers > 2 ? r.y : 0.0, u_layers > 3 ? r.z : 0.0);
    float total = r.x + r.y + r.z;
    if (total > 1.0) r /= total;
    return vec4(clamp(1.0 - (r.x + r.y + r.z), 0.0, 1.0), r);
}}
// Level `level`'s texel at uv: every layer's values, the normalised weights, the normal's x, y.
HbrdfViewShading hbrdf_view_level(vec2 uv, int level) {{
    HbrdfViewShading s;
    for (int k = 0; k < 4; ++k) hbrdf_view_layer(k, uv, level, s);
    s.w = hbrdf_view_weights(uv, level);
    s.nxy = u_plane_normal >= 0 ? hbrdf_view_map(u_plane_normal, uv, level).xy : vec2(0.0);
    return s;
}}
// The texel at uv and level of detail lod: libhybridbrdf's trilinear Svbrdf::texel (each of the two
// levels around lod read bilinearly, normalised, then their values mixed by the fraction).
HbrdfViewShading hbrdf_view_shading_at(vec2 uv, float lod) {{
    float d = clamp(lod, 0.0, float(u_map_levels - 1));
    int fine = int(d);
    float t = d - float(fine);
    HbrdfViewShading s = hbrdf_view_level(uv, fine);
    if (t > 0.0 && fine + 1 < u_map_levels) {{
        HbrdfViewShading c = hbrdf_view_level(uv, fine + 1);
        for (int k = 0; k < 4; ++k) {{
            s.kd[k] = s.kd[k] * (1.0 - t) + c.kd[k] * t;
            s.eta[k] = s.eta[k] * (1.0 - t) + c.eta[k] * t;
            s.alpha[k] = s.alpha[k] * (1.0 - t) + c.alpha[k] * t;
        }}
        for (int i = 0; i < 4 * {z_len}; ++i) s.z[i] = s.z[i] * (1.0 - t) + c.z[i] * t;
        s.w = s.w * (1.0 - t) + c.w * t;
        s.nxy = s.nxy * (1.0 - t) + c.nxy * t;
    }}
    s.ts = vec3(1.0, 0.0, 0.0);
    s.bs = vec3(0.0, 1.0, 0.0);
    s.ns = vec3(0.0, 0.0, 1.0);
    if (u_plane_normal >= 0) {{  // libhybridbrdf's normal_map.hpp: x, y filtered, z rebuilt, Gram-Schmidt tangent
        vec2 xy = s.nxy;
        s.ns = normalize(vec3(xy, sqrt(max(0.0, 1.0 - dot(xy, xy)))));
        vec3 t = s.ts - s.ns * s.ns.x;
        s.ts = normalize(dot(t, t) > 1e-12 ? t : cross(s.bs, s.ns));
        s.bs = cross(s.ns, s.ts);
    }}
    return s;
}}
// The tracer's sphere uv of unit normal n.
vec2 hbrdf_view_uv(vec3 n) {{
    const float INV_PI = 0.318309886183791;
    return vec2(atan(n.z, n.x) * (0.5 * INV_PI) + 0.5, acos(clamp(n.y, -1.0, 1.0)) * INV_PI);
}}
// The sphere's uv through film point p (pixels, y down; the pinhole of hbrdf_view_radiance); false
// where the ray misses the sphere.
bool hbrdf_view_film_uv(vec2 p, out vec2 uv) {{
    float sx = (2.0 * p.x / u_size.x - 1.0) * u_tan.x, sy = (1.0 - 2.0 * p.y / u_size.y) * u_tan.y;
    vec3 d = normalize(u_cam_fwd + u_cam_right * sx + u_cam_up * sy);
    float b = dot(u_cam_pos, d), disc = b * b - (dot(u_cam_pos, u_cam_pos) - 1.0);
    uv = vec2(0.0);
    if (disc <= 0.0) return false;
    uv = hbrdf_view_uv(normalize(u_cam_pos + (-b - sqrt(disc)) * d));
    return true;
}}
// The texel at the sphere's point n seen through film point p. With a mip chain, its level of detail
// is libhybridbrdf's Svbrdf::lod of the uv differences to the pixels right and below (level 0
// where either misses the sphere; u's difference taken across the seam u = 0 | 1).
HbrdfViewShading hbrdf_view_shading(vec3 n, vec2 p) {{
    vec2 uv = hbrdf_view_uv(n), ux, uy;
    float lod = 0.0;
    if (u_map_levels > 1 && hbrdf_view_film_uv(p + vec2(1.0, 0.0), ux) && hbrdf_view_film_uv(p + vec2(0.0, 1.0), uy)) {{
        vec2 a = ux - uv, b = uy - uv;
        a.x -= floor(a.x + 0.5);
        b.x -= floor(b.x + 0.5);
        a *= vec2(u_map_size);
        b *= vec2(u_map_size);
        lod = 0.5 * log2(max(max(dot(a, a), dot(b, b)), 1e-30));
    }}
    return hbrdf_view_shading_at(uv, lod);
}}
// hbrdf_pdf_layers: sum_k w_k hbrdf_pdf(wi, wo, m_k) over the layers of positive weight, in order;
// wi, wo in the sphere's frame (with a normal map: the rule, then the shading frame's coordinates).
float hbrdf_view_pdf(vec3 wi, vec3 wo, HbrdfViewShading s) {{
    if (u_plane_normal >= 0) {{
        if (!hbrdf_view_above(s, wi, wo)) return 0.0;
        wi = hbrdf_view_to_shading(s, wi);
        wo = hbrdf_view_to_shading(s, wo);
    }}
    float p = 0.0;
    for (int k = 0; k < 4; ++k) {{
        if (s.w[k] > 0.0) p = p + s.w[k] * hbrdf_pdf(wi, wo, hbrdf_view_material(s, k));
    }}
    return p;
}}
// hbrdf_sample_layers: layer k with probability w_k (the first of positive weight whose interval
// holds u.x, else the last of positive weight; u.x rescaled to it), then its hbrdf_sample.
vec3 hbrdf_view_sample(vec3 wo, vec2 u_in, HbrdfViewShading s, out float pdf) {{
    float ux = hbrdf_clamp_lo(u_in.x, 0.0, HBRDF_ONE_MINUS_EPS);
    int layer = 0;
    float start = 0.0, end = 0.0, w = s.w.x;
    bool found = false;
    for (int k = 0; k < 4; ++k) {{
        float wk = s.w[k];
        if (k == 0 || (!found && wk > 0.0)) {{
            layer = k;
            start = end;
            w = wk;
            found = wk > 0.0 && ux < end + wk;  // the last layer takes the rest
        }}
        end = end + (wk > 0.0 ? wk : 0.0);
    }}
    vec2 u = vec2(hbrdf_clamp_lo(w > 0.0 ? (ux - start) / w : ux, 0.0, HBRDF_ONE_MINUS_EPS), u_in.y);
    float pdf_k = 0.0;
    bool mapped = u_plane_normal >= 0;  // drawn in the shading frame, returned in the sphere's
    vec3 wi = hbrdf_sample(mapped ? hbrdf_view_to_shading(s, wo) : wo, u, hbrdf_view_material(s, layer), pdf_k);
    if (mapped) wi = s.ts * wi.x + s.bs * wi.y + s.ns * wi.z;
    pdf = pdf_k > 0.0 ? hbrdf_view_pdf(wi, wo, s) : 0.0;
    return wi;
}}
// One call site of the network: a loop over (direction, layer); each direction's texel f is summed
// over the layers first (hbrdf_eval_layers' order), then clipped at 0 and weighted as the uniform page does.
vec3 hbrdf_view_reflected(vec3 wo, HbrdfViewShading s, int count, vec3 wi0, vec3 weight0, vec3 wi1, vec3 weight1) {{
    vec3 sum = vec3(0.0), f = vec3(0.0);
    for (int j = 0; j < 2 * 4; ++j) {{
        int k = j % 4;
        if (j / 4 >= count) break;
        vec3 wi = j < 4 ? wi0 : wi1, weight = j < 4 ? weight0 : weight1;
        float w = s.w[k];
        bool mapped = u_plane_normal >= 0;
        if (w > 0.0 && wi.z > 0.0 && any(greaterThan(weight, vec3(0.0))) && (!mapped || hbrdf_view_above(s, wi, wo))) {{
            HbrdfMaterial m = hbrdf_view_material_full(s, k);
            vec3 a = mapped ? hbrdf_view_to_shading(s, wi) : wi, b = mapped ? hbrdf_view_to_shading(s, wo) : wo;
            f += (u_analytic ? hbrdf_eval_analytic(a, b, m) : hbrdf_eval(a, b, m)) * w;
        }}
        if (k == 3) {{
            if (wi.z > 0.0 && any(greaterThan(weight, vec3(0.0)))) sum += max(f, vec3(0.0)) * wi.z * weight;
            f = vec3(0.0);
        }}
    }}
    return sum;
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


def _head_lines(z_len: int, head_w: int, n_out: int, energy: int, packed: str) -> str:
    """GLSL lines filling a material's head and energy table from its packed floats (``packed``:
    the accessor with ``{}`` for the index)."""
    lines = ""
    if head_w:
        lines = (f"    for (int i = 0; i < {head_w}; ++i) m.head_w[i] = {packed.format(f'{z_len} + i')};\n"
                 f"    for (int i = 0; i < {n_out}; ++i) m.head_b[i] = {packed.format(f'{z_len + head_w} + i')};\n")
    if energy:
        at = z_len + (head_w + n_out if head_w else 0)
        lines += f"    for (int i = 0; i < {energy}; ++i) m.energy[i] = {packed.format(f'{at} + i')};\n"
    return lines


def fragment_shader(glsl: str, z_len: int, n_pack: int, head_w: int = 0, n_out: int = 0, energy: int = 0,
                    textured: bool = False) -> str:
    """The page's fragment shader (GLSL ES 3.00): :data:`ES_PREFIX`, ``glsl`` (``hbrdf-codegen --target
    glsl`` output, unchanged) and the page's ``main``. ``head_w``/``n_out``: the material output
    layer's sizes (0 for a shared one); ``energy``: the energy-bound table's length (0 for none); the
    packed uniforms hold z, then head_w, then head_b, then the table. ``textured``: the shading
    point's material is a textured material's texel (:data:`_TEXTURED_MATERIAL`, ``hbrdf view
    --svbrdf``), else the one material of the uniforms."""
    n_vec = (n_pack + 3) // 4
    if textured:
        material = _TEXTURED_MATERIAL.format(
            n_vec=n_vec, n_layer_vec=4 * n_vec, z_len=z_len,
            layer_head_lines=_head_lines(z_len, head_w, n_out, energy, "hbrdf_view_packed(kk, {})"))
    else:
        material = _UNIFORM_MATERIAL.format(n_vec=n_vec, z_len=z_len,
                                            head_lines=_head_lines(z_len, head_w, n_out, energy, "hbrdf_view_packed({})"))
    return ES_PREFIX + glsl + _MAIN.format(material=material)


__all__ = ["DISPLAY_SHADER", "ES_PREFIX", "fragment_shader"]
