"""The WGSL of ``hbrdf view``'s WebGPU backend (docs/VIEWER.md, "WebGPU").

:func:`compute_shader` is ``hbrdf-codegen --target wgsl`` output (the generated code of the same
template as every dialect, unchanged) followed by the page's own WGSL: a port of the GLSL ES
``main`` of :mod:`hybridbrdf.viewer.glsl` (``glsl._MAIN``) as a compute shader that adds one sample
per pixel to a storage buffer of sums per dispatch. It computes what the WebGL2 shader computes,
operation by operation: the same random numbers (a Weyl sequence in 32-bit fixed point shifted
per pixel by a hash, of the pixel counted from the bottom row as ``gl_FragCoord`` counts it), the
tracer's equirect mapping and the map's rotation, the same sampling tables (built by the page's
script) and binary search, the power heuristic of one map sample and one ``hbrdf_sample`` sample,
the sun alone as one exact sample at the pixel's centre, and the map behind the sphere.

The material comes from a uniform buffer (kd, eta, alpha and the packed latent code and
output-layer head, as the WebGL2 page's uniforms), so the picker and the sliders never recompile.
The environment's texels and its sampling tables are read-only storage buffers.

:data:`DISPLAY_SHADER` is the display pass (a full-screen triangle): the mean of the sums,
2^exposure x, clipped to [0, 1], the sRGB OETF, exactly as ``glsl.DISPLAY_SHADER``.

Bindings (the page's viewer_webgpu.js creates them with explicit layouts):

- compute, group 0: 0 ``HbrdfViewParams`` (uniform), 1 the sample index (uniform), 2 the sums
  (storage, read_write, ``array<vec4f>``: rgb = sum of radiance, a = number of samples; pixel
  (x, y) with y from the top row at ``y * size + x``), 3 the map's texels (storage, read:
  ``array<vec4f>``, rgb radiance and a the texel's density over (u, v), rows from the zenith
  down), 4 the sampling tables (storage, read: ``array<f32>``, the rows' CDF, H + 1 values, then
  each row's CDF, W + 1 values per row);
- display, group 0: 0 the sums (storage, read), 1 ``HbrdfViewDisplay`` (uniform: gain, size).
"""

from __future__ import annotations

#: Workgroup size of the compute pass (8 x 8 pixels).
WORKGROUP = 8

#: Bytes of ``HbrdfViewParams`` before the packed array: ten vec4 (kd, eta, alpha and the film's
#: tangent, sun, four camera vectors, the map's rotation and the canvas size, flags).
PARAMS_HEAD_BYTES = 160

#: The page's WGSL after the generated code. Formatted with ``n_vec``, ``z_len``, ``head_lines``.
_MAIN = """
// ---- hbrdf view: one unit sphere at the origin (docs/VIEWER.md, WebGPU) ----
struct HbrdfViewParams {{
    kd: vec4f,         // xyz
    eta: vec4f,        // xyz
    alpha: vec4f,      // alpha_x, alpha_y, then tan of the half field of view (x, y)
    sun: vec4f,        // the sun's direction (world), its irradiance
    cam_pos: vec4f,
    cam_fwd: vec4f,
    cam_right: vec4f,
    cam_up: vec4f,
    env: vec4f,        // cos, sin of the map's rotation_deg about +y; the canvas's width, height
    flags: vec4u,      // analytic (0/1), light (0 the sun alone, 1 the map), the map's width, height
    pack: array<vec4f, {n_vec}>,  // the latent code, then the output layer's weights and biases
}};
struct HbrdfViewFrame {{
    sample_index: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}};
@group(0) @binding(0) var<uniform> hbrdf_view_params: HbrdfViewParams;
@group(0) @binding(1) var<uniform> hbrdf_view_frame: HbrdfViewFrame;
@group(0) @binding(2) var<storage, read_write> hbrdf_view_accum: array<vec4f>;
@group(0) @binding(3) var<storage, read> hbrdf_view_env_texels: array<vec4f>;
@group(0) @binding(4) var<storage, read> hbrdf_view_env_cdf: array<f32>;

const HBRDF_VIEW_PI: f32 = 3.14159265358979f;
// The largest float below 1: u = 1 would index one texel past the map.
const HBRDF_VIEW_ONE_MINUS_EPS: f32 = 0.99999994f;

fn hbrdf_view_packed(i: i32) -> f32 {{ return hbrdf_view_params.pack[i / 4][i % 4]; }}
fn hbrdf_view_material() -> HbrdfMaterial {{
    var m: HbrdfMaterial;
    m.kd = hbrdf_view_params.kd.xyz;
    m.eta = hbrdf_view_params.eta.xyz;
    m.alpha_x = hbrdf_view_params.alpha.x;
    m.alpha_y = hbrdf_view_params.alpha.y;
    for (var i: i32 = 0; i < {z_len}; i++) {{ m.z[i] = hbrdf_view_packed(i); }}
{head_lines}    return m;
}}
fn hbrdf_view_env_width() -> i32 {{ return i32(hbrdf_view_params.flags.z); }}
fn hbrdf_view_env_height() -> i32 {{ return i32(hbrdf_view_params.flags.w); }}

// Random numbers: a Kronecker (Weyl) sequence in 6 dimensions, its steps the powers of 1 / g with
// g^7 = g + 1 (Roberts 2018), in 32-bit fixed point (u32 arithmetic wraps, as GLSL's uint), shifted
// per pixel by a hash (Cranley-Patterson rotation): the WebGL2 shader's numbers, bit for bit.
fn hbrdf_view_hash(x_in: u32) -> u32 {{
    var x: u32 = x_in;
    x = x ^ (x >> 16u);
    x = x * 0x7feb352du;
    x = x ^ (x >> 15u);
    x = x * 0x846ca68bu;
    x = x ^ (x >> 16u);
    return x;
}}
fn hbrdf_view_unit(x: u32) -> f32 {{ return f32(x >> 8u) * (1.0f / 16777216.0f); }}
struct HbrdfViewRandom {{
    u: vec4f,
    jitter: vec2f,
}};
fn hbrdf_view_random(pixel: vec2u, index: u32) -> HbrdfViewRandom {{
    let h: u32 = hbrdf_view_hash((pixel.x * 0x9e3779b9u) ^ hbrdf_view_hash(pixel.y + 0x632be5abu));
    var r: HbrdfViewRandom;
    r.u = vec4f(hbrdf_view_unit(index * 0xe6ab68f2u + h), hbrdf_view_unit(index * 0xcef33b7fu + hbrdf_view_hash(h + 1u)),
                hbrdf_view_unit(index * 0xba44a09bu + hbrdf_view_hash(h + 2u)),
                hbrdf_view_unit(index * 0xa92dd2afu + hbrdf_view_hash(h + 3u)));
    r.jitter = vec2f(hbrdf_view_unit(index * 0x9a8c3a5du + hbrdf_view_hash(h + 4u)),
                     hbrdf_view_unit(index * 0x8c1e4b51u + hbrdf_view_hash(h + 5u)));
    return r;
}}

// The tracer's equirect mapping (EnvironmentLight): theta from +y, phi = atan2(x, -z) in the map's
// frame, which is the world turned by -rotation about +y.
fn hbrdf_view_env_uv(d: vec3f) -> vec2f {{
    let rot: vec2f = hbrdf_view_params.env.xy;
    let mx: f32 = rot.x * d.x - rot.y * d.z;
    let mz: f32 = rot.y * d.x + rot.x * d.z;
    let theta: f32 = acos(clamp(d.y, -1.0f, 1.0f));
    var phi: f32 = atan2(mx, -mz);
    if (phi < 0.0f) {{ phi = phi + 2.0f * HBRDF_VIEW_PI; }}
    return min(vec2f(phi / (2.0f * HBRDF_VIEW_PI), theta / HBRDF_VIEW_PI), vec2f(HBRDF_VIEW_ONE_MINUS_EPS));
}}
fn hbrdf_view_env_direction(uv: vec2f) -> vec3f {{
    let rot: vec2f = hbrdf_view_params.env.xy;
    let theta: f32 = uv.y * HBRDF_VIEW_PI;
    let phi: f32 = uv.x * 2.0f * HBRDF_VIEW_PI;
    let s: f32 = sin(theta);
    let mx: f32 = s * sin(phi);
    let my: f32 = cos(theta);
    let mz: f32 = -s * cos(phi);
    return vec3f(rot.x * mx + rot.y * mz, my, -rot.y * mx + rot.x * mz);
}}
fn hbrdf_view_env_texel(uv: vec2f) -> vec4f {{
    let w: i32 = hbrdf_view_env_width();
    let h: i32 = hbrdf_view_env_height();
    let x: i32 = min(i32(uv.x * f32(w)), w - 1);
    let y: i32 = min(i32(uv.y * f32(h)), h - 1);
    return hbrdf_view_env_texels[y * w + x];
}}
// Solid-angle density of a map sample toward d (d omega = 2 pi^2 sin(theta) du dv); sin(theta)
// from x and z, which does not cancel near the poles as sqrt(1 - y^2) does.
fn hbrdf_view_env_pdf(d: vec3f, texel: vec4f) -> f32 {{
    let sin_theta: f32 = sqrt(d.x * d.x + d.z * d.z);
    if (sin_theta > 0.0f) {{ return texel.a / (2.0f * HBRDF_VIEW_PI * HBRDF_VIEW_PI * sin_theta); }}
    return 0.0f;
}}
// The bin of a piecewise-constant distribution for u in [0, 1): the largest i < n with cdf[i] <= u
// (bins of zero probability are never chosen), and where u falls inside it. The CDF's n + 1 values
// start at hbrdf_view_env_cdf[start].
fn hbrdf_view_invert_cdf(start: i32, n: i32, u: f32) -> f32 {{
    var lo: i32 = 0;
    var hi: i32 = n;  // cdf[lo] <= u < cdf[hi] = 1
    while (lo + 1 < hi) {{
        let mid: i32 = (lo + hi) / 2;
        if (hbrdf_view_env_cdf[start + mid] <= u) {{ lo = mid; }} else {{ hi = mid; }}
    }}
    let c0: f32 = hbrdf_view_env_cdf[start + lo];
    let c1: f32 = hbrdf_view_env_cdf[start + lo + 1];
    var du: f32 = 0.5f;
    if (c1 > c0) {{ du = clamp((u - c0) / (c1 - c0), 0.0f, 1.0f); }}
    return min((f32(lo) + du) / f32(n), HBRDF_VIEW_ONE_MINUS_EPS);
}}
struct HbrdfViewEnvSample {{
    d: vec3f,
    texel: vec4f,
    pdf: f32,
}};
fn hbrdf_view_env_sample(u: vec2f) -> HbrdfViewEnvSample {{
    let w: i32 = hbrdf_view_env_width();
    let h: i32 = hbrdf_view_env_height();
    let v: f32 = hbrdf_view_invert_cdf(0, h, u.y);
    let row: i32 = min(i32(v * f32(h)), h - 1);
    let uu: f32 = hbrdf_view_invert_cdf(h + 1 + row * (w + 1), w, u.x);
    var s: HbrdfViewEnvSample;
    s.d = hbrdf_view_env_direction(vec2f(uu, v));
    s.texel = hbrdf_view_env_texel(vec2f(uu, v));
    s.pdf = hbrdf_view_env_pdf(s.d, s.texel);
    return s;
}}
// The directions of one sample of the reflected radiance toward wo (local frame tg, bt, n), each
// with the factor its f(wi, wo) cos(theta_i) is multiplied by: a map sample and a BRDF sample, each
// weighted by the power heuristic (w / p = p / (p^2 + q^2)); the sun alone: its direction and E.
// The BRDF is evaluated in one place (hbrdf_view_radiance's loop), as in the WebGL2 shader.
struct HbrdfViewDirections {{
    count: i32,
    wi0: vec3f,
    weight0: vec3f,
    wi1: vec3f,
    weight1: vec3f,
}};
fn hbrdf_view_directions(wo: vec3f, tg: vec3f, bt: vec3f, n: vec3f, m: HbrdfMaterial, u: vec4f) -> HbrdfViewDirections {{
    var r: HbrdfViewDirections;
    if (hbrdf_view_params.flags.y == 0u) {{
        let sun: vec3f = hbrdf_view_params.sun.xyz;
        r.count = 1;
        r.wi0 = vec3f(dot(sun, tg), dot(sun, bt), dot(sun, n));
        r.weight0 = vec3f(hbrdf_view_params.sun.w);
        r.wi1 = vec3f(0.0f);
        r.weight1 = vec3f(0.0f);
        return r;
    }}
    let s: HbrdfViewEnvSample = hbrdf_view_env_sample(u.xy);
    var p_light: f32 = s.pdf;
    r.count = 2;
    r.wi0 = vec3f(dot(s.d, tg), dot(s.d, bt), dot(s.d, n));
    var p_brdf: f32 = hbrdf_pdf(r.wi0, wo, m);
    r.weight0 = vec3f(0.0f);
    if (p_light > 0.0f) {{ r.weight0 = s.texel.rgb * (p_light / (p_light * p_light + p_brdf * p_brdf)); }}
    r.wi1 = hbrdf_sample(wo, u.zw, m, &p_brdf);
    let d: vec3f = r.wi1.x * tg + r.wi1.y * bt + r.wi1.z * n;
    let texel: vec4f = hbrdf_view_env_texel(hbrdf_view_env_uv(d));
    p_light = hbrdf_view_env_pdf(d, texel);
    r.weight1 = vec3f(0.0f);
    if (p_brdf > 0.0f) {{ r.weight1 = texel.rgb * (p_brdf / (p_brdf * p_brdf + p_light * p_light)); }}
    return r;
}}
// Radiance through the film point p (pixels, y down) from the tracer's pinhole (docs/RENDERING.md).
fn hbrdf_view_radiance(p: vec2f, u: vec4f) -> vec3f {{
    let size: vec2f = hbrdf_view_params.env.zw;
    let tan_half: vec2f = hbrdf_view_params.alpha.zw;
    let sx: f32 = (2.0f * p.x / size.x - 1.0f) * tan_half.x;
    let sy: f32 = (1.0f - 2.0f * p.y / size.y) * tan_half.y;
    let d: vec3f = normalize(hbrdf_view_params.cam_fwd.xyz + hbrdf_view_params.cam_right.xyz * sx +
                             hbrdf_view_params.cam_up.xyz * sy);
    let o: vec3f = hbrdf_view_params.cam_pos.xyz;
    let b: f32 = dot(o, d);
    let disc: f32 = b * b - (dot(o, o) - 1.0f);
    // A ray that misses the sphere sees the map behind it, as the tracer's camera rays do (the sun
    // alone is a black sky: its disc is not drawn).
    if (disc <= 0.0f) {{
        if (hbrdf_view_params.flags.y == 1u) {{ return hbrdf_view_env_texel(hbrdf_view_env_uv(d)).rgb; }}
        return vec3f(0.0f);
    }}
    let n: vec3f = normalize(o + (-b - sqrt(disc)) * d);
    // The tracer's sphere frame: tangent d p / d phi about +y (the alpha_x axis).
    var tg: vec3f = vec3f(-n.z, 0.0f, n.x);
    let len2: f32 = dot(tg, tg);
    if (len2 > 1e-12f) {{ tg = tg / sqrt(len2); }} else {{ tg = vec3f(1.0f, 0.0f, 0.0f); }}
    let bt: vec3f = cross(n, tg);
    let wo: vec3f = vec3f(dot(-d, tg), dot(-d, bt), dot(-d, n));
    if (wo.z <= 0.0f) {{ return vec3f(0.0f); }}
    let m: HbrdfMaterial = hbrdf_view_material();
    let dirs: HbrdfViewDirections = hbrdf_view_directions(wo, tg, bt, n, m, u);
    var sum: vec3f = vec3f(0.0f);
    for (var k: i32 = 0; k < dirs.count; k++) {{
        var wi: vec3f = dirs.wi0;
        var weight: vec3f = dirs.weight0;
        if (k == 1) {{ wi = dirs.wi1; weight = dirs.weight1; }}
        if (wi.z > 0.0f && any(weight > vec3f(0.0f))) {{
            var f: vec3f;
            if (hbrdf_view_params.flags.x != 0u) {{ f = hbrdf_eval_analytic(wi, wo, m); }} else {{ f = hbrdf_eval(wi, wo, m); }}
            sum = sum + max(f, vec3f(0.0f)) * wi.z * weight;
        }}
    }}
    return sum;
}}
// One sample per pixel per dispatch, added to the pixel's sums (the page dispatches again for more).
@compute @workgroup_size({wg}, {wg})
fn hbrdf_view_main(@builtin(global_invocation_id) id: vec3u) {{
    let width: u32 = u32(hbrdf_view_params.env.z);
    let height: u32 = u32(hbrdf_view_params.env.w);
    if (id.x >= width || id.y >= height) {{ return; }}
    // The WebGL2 shader's pixel: gl_FragCoord counts rows from the bottom.
    let r: HbrdfViewRandom = hbrdf_view_random(vec2u(id.x, height - 1u - id.y), hbrdf_view_frame.sample_index);
    // The sun alone is one sample at the pixel's centre; the map's are spread over the pixel.
    var p: vec2f = vec2f(f32(id.x) + 0.5f, f32(id.y) + 0.5f);
    if (hbrdf_view_params.flags.y == 1u) {{ p = vec2f(f32(id.x), f32(id.y)) + r.jitter; }}
    let i: u32 = id.y * width + id.x;
    hbrdf_view_accum[i] = hbrdf_view_accum[i] + vec4f(hbrdf_view_radiance(p, r.u), 1.0f);
}}
"""

#: The display pass: the mean of the sums, 2^exposure x, clipped to [0, 1], the sRGB OETF (8 bits
#: in the target): glsl.DISPLAY_SHADER in WGSL. A full-screen triangle; @builtin(position) counts
#: rows from the top, as the sums are stored.
DISPLAY_SHADER = """struct HbrdfViewDisplay {
    gain: f32,
    width: u32,
    pad0: u32,
    pad1: u32,
};
@group(0) @binding(0) var<storage, read> hbrdf_view_accum: array<vec4f>;
@group(0) @binding(1) var<uniform> hbrdf_view_display: HbrdfViewDisplay;
@vertex
fn hbrdf_view_vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4f {
    let v: vec2f = vec2f(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4f(v * 2.0f - 1.0f, 0.0f, 1.0f);
}
fn hbrdf_view_srgb(x_in: f32) -> f32 {
    let x: f32 = clamp(x_in, 0.0f, 1.0f);
    if (x <= 0.0031308f) { return 12.92f * x; }
    return 1.055f * pow(x, 1.0f / 2.4f) - 0.055f;
}
@fragment
fn hbrdf_view_fragment(@builtin(position) position: vec4f) -> @location(0) vec4f {
    let px: vec2u = vec2u(position.xy);
    let acc: vec4f = hbrdf_view_accum[px.y * hbrdf_view_display.width + px.x];
    var c: vec3f = vec3f(0.0f);
    if (acc.a > 0.0f) { c = acc.rgb / acc.a; }
    c = c * hbrdf_view_display.gain;
    return vec4f(hbrdf_view_srgb(c.r), hbrdf_view_srgb(c.g), hbrdf_view_srgb(c.b), 1.0f);
}
"""


def compute_shader(wgsl: str, z_len: int, n_pack: int, head_w: int = 0, n_out: int = 0, energy: int = 0) -> str:
    """The page's WebGPU compute shader: ``wgsl`` (``hbrdf-codegen --target wgsl`` output, unchanged)
    and the page's WGSL (entry point ``hbrdf_view_main``). ``z_len``: the generated struct's latent
    length; ``n_pack``: floats per material in the packed array (z, then head_w, then head_b);
    ``head_w``/``n_out``: the material output layer's sizes (0 for a shared one)."""
    head_lines = ""
    if head_w:
        head_lines = (f"    for (var i: i32 = 0; i < {head_w}; i++) {{ m.head_w[i] = hbrdf_view_packed({z_len} + i); }}\n"
                      f"    for (var i: i32 = 0; i < {n_out}; i++) {{ m.head_b[i] = hbrdf_view_packed({z_len + head_w} + i); }}\n")
    if energy:
        at = z_len + (head_w + n_out if head_w else 0)
        head_lines += f"    for (var i: i32 = 0; i < {energy}; i++) {{ m.energy[i] = hbrdf_view_packed({at} + i); }}\n"
    return wgsl + _MAIN.format(n_vec=max(1, (n_pack + 3) // 4), z_len=z_len, head_lines=head_lines, wg=WORKGROUP)


__all__ = ["DISPLAY_SHADER", "PARAMS_HEAD_BYTES", "WORKGROUP", "compute_shader"]
