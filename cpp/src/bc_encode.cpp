// libhybridbrdf — a BC4 (and BC5: two BC4 blocks) encoder for data maps (hybridbrdf/bc.hpp;
// docs/TEXTURES.md, "Encoders"). Block layout from the Khronos Data Format Specification
// (RGTC); the search is this library's own.
//
// Why not min/max endpoints (what the PyPI encoders measured in bench/bc_encoders.py do): a
// steep ramp in a block (a mask's edge: a weights map's texels between two layers) holds a few
// evenly spaced values, and an eight-level palette stretched from the block's minimum to its
// maximum puts its levels between them (up to 11 steps of 1/255 off). The palette whose spacing
// is the data's lies partly *outside* the block's range: min at level a, max at level b of the
// palette, a < b anywhere in 0..7. Searching every (a, b) and the rounded endpoints around each
// finds it (a 49..206 ramp of seven values: squared error 749 -> 13, worst texel 11 -> 2 steps).
//
// The error minimised is the sum of squared differences of the decoded bytes (the decoder of
// bc.cpp: interpolants floored), under one constraint: a texel stored as 0 or 255 decodes to
// exactly that. A weight of exactly 0 or 1 (a layer absent or alone) stays so, and a layer does
// not come back faintly where it was painted out.
#include "hybridbrdf/bc.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

namespace hbrdf::bc {

namespace {

constexpr int kRefinedStarts = 4;

struct Candidate {
    long error = std::numeric_limits<long>::max();
    int e0 = 0, e1 = 0;
};

// Squared error of the block under (e0, e1), or max() where a 0 or 255 texel is not kept exactly.
long bc4_error(const std::uint8_t v[16], int e0, int e1) {
    int palette[8];
    bc4_palette(e0, e1, palette);
    long total = 0;
    for (int t = 0; t < 16; ++t) {
        int best = 1 << 20;
        for (int i = 0; i < 8; ++i) best = std::min(best, std::abs(int(v[t]) - palette[i]));
        if (best != 0 && (v[t] == 0 || v[t] == 255)) return std::numeric_limits<long>::max();
        total += long(best) * best;
    }
    return total;
}

void consider(const std::uint8_t v[16], int e0, int e1, Candidate& best) {
    if (e0 < 0 || e0 > 255 || e1 < 0 || e1 > 255) return;
    const long error = bc4_error(v, e0, e1);
    if (error < best.error) best = {error, e0, e1};
}

// Palettes of `levels` evenly spaced values (8: e1 < ... < e0; 6: e0 < ... < e1) that put lo at
// level a and hi at level b, each endpoint rounded and its two neighbours; the best of each
// (a, b) appended to `starts` (at most 28).
void search(const std::uint8_t v[16], int lo, int hi, int levels, Candidate& best, Candidate* starts, int& n) {
    for (int a = 0; a < levels - 1 && best.error; ++a)
        for (int b = a + 1; b < levels && best.error; ++b) {
            const double step = double(hi - lo) / double(b - a);
            const double low = lo - a * step, high = low + (levels - 1) * step;
            const int l = int(std::lround(low)), h = int(std::lround(high));
            Candidate local;
            for (int dl = -1; dl <= 1; ++dl)
                for (int dh = -1; dh <= 1; ++dh) {
                    if (levels == 8 && h + dh > l + dl) consider(v, h + dh, l + dl, local);
                    if (levels == 6 && l + dl <= h + dh) consider(v, l + dl, h + dh, local);
                }
            if (local.error < best.error) best = local;
            if (local.error != std::numeric_limits<long>::max()) starts[n++] = local;
            if (hi == lo) return;  // one value: every (a, b) is the same palette
        }
}

// Least squares from the best palette's assignment of texels to levels (Castaño's and
// van Waveren's "cluster fit" for one channel): the evenly spaced levels nearest the texels they
// hold, its endpoints rounded and the neighbours within two steps tried, three times over. It
// frees the block's minimum and maximum from lying on a level (a smoothstep's curved ramp).
void refine(const std::uint8_t v[16], Candidate best, Candidate& overall) {
    for (int round = 0; round < 3 && best.error; ++round) {
        const bool eight = best.e0 > best.e1;
        const int top = eight ? 7 : 5;
        int palette[8];
        bc4_palette(best.e0, best.e1, palette);
        double s_uu = 0, s_u = 0, s_1 = 0, s_uv = 0, s_v = 0;
        for (int t = 0; t < 16; ++t) {
            int index = 0;
            for (int i = 1; i < 8; ++i)
                if (std::abs(int(v[t]) - palette[i]) < std::abs(int(v[t]) - palette[index])) index = i;
            if (!eight && index >= 6) continue;  // the six-level mode's own 0 and 255
            const int position = eight ? (index == 0 ? 7 : index == 1 ? 0 : 8 - index)
                                       : (index == 0 ? 0 : index == 1 ? 5 : index - 1);
            const double u = double(position) / top;  // v ~ (1 - u) low + u high
            s_uu += u * u, s_u += u, s_1 += 1, s_uv += u * v[t], s_v += v[t];
        }
        // Normal equations of (low, high): [(1-u)^2, u(1-u); u(1-u), u^2] sums.
        const double a = s_1 - 2 * s_u + s_uu, b = s_u - s_uu, c = s_uu;
        const double r0 = s_v - s_uv, r1 = s_uv, det = a * c - b * b;
        if (!(std::abs(det) > 1e-9)) return;
        const int low = int(std::lround((r0 * c - b * r1) / det)), high = int(std::lround((a * r1 - b * r0) / det));
        const Candidate before = best;
        for (int dl = -2; dl <= 2; ++dl)
            for (int dh = -2; dh <= 2; ++dh) {
                if (eight && high + dh > low + dl) consider(v, high + dh, low + dl, best);
                if (!eight && low + dl <= high + dh) consider(v, low + dl, high + dh, best);
            }
        if (best.e0 == before.e0 && best.e1 == before.e1) break;
    }
    if (best.error < overall.error) overall = best;
}

}  // namespace

void encode_bc4_block(const std::uint8_t values[16], std::uint8_t block[8]) {
    int lo = 255, hi = 0, inner_lo = 255, inner_hi = 0;
    for (int t = 0; t < 16; ++t) {
        lo = std::min(lo, int(values[t]));
        hi = std::max(hi, int(values[t]));
        if (values[t] != 0 && values[t] != 255) {
            inner_lo = std::min(inner_lo, int(values[t]));
            inner_hi = std::max(inner_hi, int(values[t]));
        }
    }
    Candidate best;
    consider(values, lo, lo, best);  // a flat block: six-level mode, every texel e0 (exact)
    if (best.error) {
        if (inner_lo > inner_hi) inner_lo = inner_hi = 0;  // only 0 and 255: the six-level mode's own
        Candidate starts[43];
        int n = 0;
        search(values, inner_lo, inner_hi, 6, best, starts, n);  // 0 and 255 exact, the rest on six levels
        search(values, lo, hi, 8, best, starts, n);
        // Least squares from the four best starts: one start alone stops in a local minimum (a
        // block's squared error 361 where the best palette has 111).
        std::partial_sort(starts, starts + std::min(n, kRefinedStarts), starts + n,
                          [](const Candidate& x, const Candidate& y) { return x.error < y.error; });
        for (int i = 0; i < std::min(n, kRefinedStarts) && best.error; ++i) refine(values, starts[i], best);
    }
    int palette[8];
    bc4_palette(best.e0, best.e1, palette);
    std::uint64_t indices = 0;
    for (int t = 0; t < 16; ++t) {
        int index = 0;
        for (int i = 1; i < 8; ++i)
            if (std::abs(int(values[t]) - palette[i]) < std::abs(int(values[t]) - palette[index])) index = i;
        indices |= std::uint64_t(index) << (3 * t);
    }
    block[0] = std::uint8_t(best.e0);
    block[1] = std::uint8_t(best.e1);
    for (int i = 0; i < 6; ++i) block[2 + i] = std::uint8_t(indices >> (8 * i));
}

void encode_level(BlockFormat format, const std::uint8_t* texels, std::uint32_t width, std::uint32_t height,
                  int channels, std::uint8_t* blocks) {
    const int used = format == BlockFormat::BC4 ? 1 : format == BlockFormat::BC5 ? 2 : 0;
    if (!used) throw std::invalid_argument("encode_level encodes BC4 and BC5 only");
    if (channels < used || width < 1 || height < 1)
        throw std::invalid_argument("encode_level: a level of at least 1 x 1 texels and the format's channels");
    const std::uint32_t bw = (width + 3) / 4, bh = (height + 3) / 4;
    for (std::uint32_t by = 0; by < bh; ++by)
        for (std::uint32_t bx = 0; bx < bw; ++bx)
            for (int c = 0; c < used; ++c) {
                std::uint8_t values[16];
                for (std::uint32_t t = 0; t < 16; ++t) {  // an edge block repeats the level's last texels
                    const std::uint32_t x = std::min(bx * 4 + t % 4, width - 1), y = std::min(by * 4 + t / 4, height - 1);
                    values[t] = texels[(std::size_t(y) * width + x) * std::size_t(channels) + std::size_t(c)];
                }
                encode_bc4_block(values, blocks + (std::size_t(by) * bw + bx) * block_bytes(format) + 8 * std::size_t(c));
            }
}

}  // namespace hbrdf::bc
