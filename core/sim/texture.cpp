#include "nirslam/sim/texture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "layout.hpp"

namespace nirslam::sim {

namespace {

// ---------------------------------------------------------------------------------------------
// Building blocks.

// 256 x 256 random values in [0, 1), the lattice of the value noise (fixed: textures vary by
// offsetting coordinates with the seed, not by changing the lattice).
struct Lattice {
  std::array<float, 256 * 256> values{};
  Lattice() {
    std::uint64_t state = 0x243F6A8885A308D3ull;
    for (float& value : values) {
      state += 0x9E3779B97F4A7C15ull;
      std::uint64_t z = state;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      z ^= z >> 31;
      value = static_cast<float>(z >> 40) * (1.0f / 16777216.0f);
    }
  }
};
// At namespace scope, so the hot noise() reads it without a guard check.
const Lattice kLattice;

inline int ifloor(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i) ? 1 : 0);
}

inline std::uint32_t hash(int a, int b, std::uint32_t seed) {
  std::uint32_t h = seed * 0x9E3779B1u ^ static_cast<std::uint32_t>(a) * 0x85EBCA77u ^
                    static_cast<std::uint32_t>(b) * 0xC2B2AE3Du;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  h *= 0x297A2D39u;
  h ^= h >> 15;
  return h;
}
inline float hash01(int a, int b, std::uint32_t seed) {
  return static_cast<float>(hash(a, b, seed) >> 8) * (1.0f / 16777216.0f);
}

inline float clamp01(float x) { return std::min(std::max(x, 0.0f), 1.0f); }
inline float mix(float a, float b, float t) { return a + (b - a) * t; }
inline float smoothstep(float a, float b, float x) {
  const float t = clamp01((x - a) / (b - a));
  return t * t * (3.0f - 2.0f * t);
}

inline float noise(float x, float y) {
  const int ix = ifloor(x), iy = ifloor(y);
  float fx = x - static_cast<float>(ix), fy = y - static_cast<float>(iy);
  fx = fx * fx * (3.0f - 2.0f * fx);
  fy = fy * fy * (3.0f - 2.0f * fy);
  const float* L = kLattice.values.data();
  const int x0 = ix & 255, x1 = (ix + 1) & 255;
  const int y0 = (iy & 255) << 8, y1 = ((iy + 1) & 255) << 8;
  const float a = L[y0 + x0], b = L[y0 + x1], c = L[y1 + x0], d = L[y1 + x1];
  return a + (b - a) * fx + (c - a) * fy + (a - b - c + d) * fx * fy;
}

// How much of a feature of spatial frequency f (cycles per metre) survives a footprint fw:
// all of it up to a quarter cycle per footprint, none from half a cycle (Nyquist) on.
inline float keep(float f, float fw) { return clamp01(2.0f - 4.0f * f * fw); }

// Noise at frequency (fu, fv), faded to its mean 0.5 where the footprint cannot resolve it.
inline float band_noise(float u, float v, float fu, float fv, float fw, float ou, float ov) {
  const float k = keep(std::max(fu, fv), fw);
  if (k <= 0.0f) return 0.5f;
  return 0.5f + k * (noise(u * fu + ou, v * fv + ov) - 0.5f);
}

// Fractal sum of `octaves` noise octaves from frequency f0, mean 0.5, range about [0, 1].
float fbm(float u, float v, float f0, int octaves, float fw, std::uint32_t seed) {
  float ou = static_cast<float>(seed & 1023u) * 0.7131f;
  float ov = static_cast<float>((seed >> 10) & 1023u) * 0.3771f;
  float sum = 0.0f, norm = 0.0f, amp = 0.5f, f = f0;
  for (int k = 0; k < octaves; ++k) {
    const float w = keep(f, fw);
    if (w > 0.0f) sum += amp * (0.5f + w * (noise(u * f + ou, v * f + ov) - 0.5f));
    else sum += amp * 0.5f;
    norm += amp;
    f *= 2.03f;
    amp *= 0.5f;
    ou += 17.31f;
    ov += 9.77f;
  }
  return sum / norm;
}

// Fraction of a box filter of width w centred at x that falls inside [a, b].
inline float box1(float x, float a, float b, float w) {
  if (w <= 1e-6f) return (x >= a && x < b) ? 1.0f : 0.0f;
  const float lo = std::max(x - 0.5f * w, a), hi = std::min(x + 0.5f * w, b);
  return clamp01((hi - lo) / w);
}
inline float rect(float u, float v, float u0, float u1, float v0, float v1, float w) {
  return box1(u, u0, u1, w) * box1(v, v0, v1, w);
}

// box1 for a position inside a cell of a periodic pattern: fades to the mean coverage when the
// footprint approaches the period (the filter then spans neighbouring cells).
inline float periodic_box(float local, float a, float b, float period, float w) {
  const float t = clamp01((w / period - 0.25f) * 4.0f);
  return mix(box1(local, a, b, w), (b - a) / period, t);
}

// Coverage of lines of width lw centred on the multiples of `period`, filtered by w.
inline float lines(float x, float period, float lw, float w) {
  const float mean = lw / period;
  const float t = clamp01((w / period - 0.25f) * 4.0f);
  if (t >= 1.0f) return mean;
  const float r = x - period * static_cast<float>(ifloor(x / period + 0.5f));
  return mix(box1(r, -0.5f * lw, 0.5f * lw, w), mean, t);
}

// Cell index and position inside the cell.
struct Cell {
  int index;
  float local;
};
inline Cell cell(float x, float size) {
  const int i = ifloor(x / size);
  return {i, x - static_cast<float>(i) * size};
}

// Per-cell random variation faded when the cell is not resolved (cells below two footprints).
inline float cell_variation(float size, float fw) { return clamp01(1.0f - fw / (0.5f * size)); }

// A small grid of random dark/bright blocks (print, pictures, glyphs): corners at a fine scale.
float blocks(float u, float v, float size, float fw, std::uint32_t seed, float lo, float hi) {
  const Cell cu = cell(u, size), cv = cell(v, size);
  const float h = hash01(cu.index, cv.index, seed);
  return mix(0.5f * (lo + hi), mix(lo, hi, h), cell_variation(size, fw));
}

// ---------------------------------------------------------------------------------------------
// Materials.

float painted_wall(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.74f + 0.08f * (fbm(u, v, 1.1f, 4, fw, seed) - 0.5f);
  a *= 1.0f - 0.12f * smoothstep(0.55f, 0.8f, fbm(u * 0.7f, v * 2.5f, 0.8f, 2, fw, seed + 5u)) *
                  clamp01(1.0f - v);  // scuffs near the floor
  a = mix(a, 0.30f, box1(v, -10.0f, 0.10f, fw));                                 // baseboard
  a = mix(a, 0.2f, box1(v, 0.10f, 0.112f, fw));                                  // its shadow line
  const Cell c = cell(u, 1.7f);
  const float h = hash01(c.index, 1, seed);
  if (h < 0.7f) {  // a framed poster or picture
    const float width = 0.45f + 0.6f * hash01(c.index, 2, seed);
    const float height = 0.35f + 0.55f * hash01(c.index, 3, seed);
    const float u0 = 0.1f + (1.5f - width) * hash01(c.index, 4, seed);
    const float v0 = 1.0f + 0.35f * hash01(c.index, 5, seed);
    const float frame = 0.025f + 0.03f * hash01(c.index, 6, seed);
    const float outer = rect(c.local, v, u0, u0 + width, v0, v0 + height, fw);
    if (outer > 0.0f) {
      const float inner = rect(c.local, v, u0 + frame, u0 + width - frame, v0 + frame, v0 + height - frame, fw);
      const float frame_albedo = hash01(c.index, 7, seed) < 0.5f ? 0.12f : 0.82f;
      const std::uint32_t picture = hash(c.index, 8, seed);
      const float block = 0.03f + 0.1f * hash01(c.index, 9, seed);
      float content = 0.6f * blocks(c.local, v, block, fw, picture, 0.08f, 0.92f) +
                      0.4f * fbm(c.local, v, 3.0f, 3, fw, picture);
      content = mix(content, 0.9f, rect(c.local, v, u0 + 0.25f * width, u0 + 0.75f * width,
                                        v0 + 0.1f * height, v0 + 0.22f * height, fw));  // caption
      a = mix(a, mix(frame_albedo, content, inner), outer);
    }
  }
  if (h > 0.45f) {  // a socket above the baseboard and a light switch
    const float su = 0.2f + 1.2f * hash01(c.index, 10, seed);
    a = mix(a, 0.45f, rect(c.local, v, su, su + 0.085f, 0.28f, 0.365f, fw));
    a = mix(a, 0.86f, rect(c.local, v, su + 0.008f, su + 0.077f, 0.288f, 0.357f, fw));
    a = mix(a, 0.25f, rect(c.local, v, su + 0.03f, su + 0.055f, 0.31f, 0.335f, fw));
    if (h > 0.8f) a = mix(a, 0.88f, rect(c.local, v, su, su + 0.08f, 1.05f, 1.13f, fw));
  }
  return a;
}

float concrete(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.36f + 0.26f * (fbm(u, v, 0.7f, 4, fw, seed) - 0.5f);
  const float pits = band_noise(u, v, 45.0f, 45.0f, fw, 3.1f, 7.7f);
  a *= 1.0f - 0.45f * smoothstep(0.72f, 0.85f, pits);
  a *= 0.78f + 0.22f * band_noise(u, v, 2.5f, 0.25f, fw, 11.0f, 5.0f);  // streaks
  a *= 1.0f - 0.45f * std::max(lines(u, 2.4f, 0.012f, fw), lines(v, 1.2f, 0.012f, fw));  // formwork joints
  // Tie holes in the middle of each formwork panel half.
  const Cell cu = cell(u + 0.3f, 0.6f), cv = cell(v + 0.3f, 0.6f);
  a = mix(a, 0.08f, rect(cu.local, cv.local, 0.285f, 0.315f, 0.285f, 0.315f, fw));
  return a;
}

float tunnel_lining(float u, float v, float fw, std::uint32_t seed) {
  // u: arc length from the bottom (|u| up to pi * 1.8), v: along the tunnel.
  float a = 0.40f + 0.26f * (fbm(u, v, 0.6f, 4, fw, seed) - 0.5f);
  const float pits = band_noise(u, v, 40.0f, 40.0f, fw, 1.3f, 2.9f);
  a *= 1.0f - 0.4f * smoothstep(0.7f, 0.85f, pits);
  const float streak = band_noise(u, v, 0.35f, 3.0f, fw, 4.0f, 8.0f);  // water runs down (along u)
  a *= 1.0f - 0.35f * smoothstep(0.55f, 0.8f, streak);
  const float ring = lines(v, 1.5f, 0.022f, fw);
  const float segment = lines(u, 1.885f, 0.016f, fw);
  a *= 1.0f - 0.55f * std::max(ring, segment);
  // Bolt pockets beside every ring joint, in the middle of each segment.
  const Cell cu = cell(u, 1.885f), cv = cell(v + 0.75f, 1.5f);
  const float pocket = rect(cu.local, cv.local, 0.9f, 0.98f, 0.62f, 0.70f, fw) +
                       rect(cu.local, cv.local, 0.9f, 0.98f, 0.80f, 0.88f, fw);
  a = mix(a, 0.10f, clamp01(pocket));
  // A painted guide line along the wall and a sign every 12 m.
  a = mix(a, 0.72f, box1(u, 2.30f, 2.36f, fw) + box1(u, -2.36f, -2.30f, fw));
  const Cell sign = cell(v, 12.0f);
  if (hash01(sign.index, 3, seed) < 0.8f) {
    const float su = hash01(sign.index, 4, seed) < 0.5f ? 1.6f : -2.1f;
    const float s = rect(u, sign.local, su, su + 0.45f, 4.0f, 4.6f, fw);
    if (s > 0.0f) {
      const float inside = rect(u, sign.local, su + 0.03f, su + 0.42f, 4.03f, 4.57f, fw);
      const float glyphs = blocks(u - su, sign.local, 0.05f, fw, hash(sign.index, 5, seed), 0.1f, 0.9f);
      a = mix(a, mix(0.15f, glyphs > 0.5f ? 0.88f : 0.12f, inside), s);
    }
  }
  return a;
}

float floor_tiles(float u, float v, float fw, std::uint32_t seed) {
  const float size = 0.45f;
  const Cell cu = cell(u, size), cv = cell(v, size);
  float a = 0.55f + 0.16f * cell_variation(size, fw) * (hash01(cu.index, cv.index, seed) - 0.5f);
  a *= 0.9f + 0.2f * fbm(u, v, 4.0f, 3, fw, seed);
  return mix(a, 0.22f, std::max(lines(u, size, 0.006f, fw), lines(v, size, 0.006f, fw)));
}

float wood_floor(float u, float v, float fw, std::uint32_t seed) {
  const float width = 0.16f, length = 1.4f;
  const Cell row = cell(u, width);
  const float offset = length * hash01(row.index, 0, seed);
  const Cell plank = cell(v + offset, length);
  const float variation = cell_variation(width, fw);
  float a = 0.52f + 0.2f * variation * (hash01(row.index, plank.index, seed) - 0.5f);
  a *= 0.88f + 0.24f * band_noise(u, v, 55.0f, 2.5f, fw, static_cast<float>(row.index) * 3.7f, 1.0f);
  a *= 1.0f - 0.15f * smoothstep(0.6f, 0.9f, band_noise(u, v, 20.0f, 6.0f, fw, 5.0f, 2.0f));  // knots
  const float gaps = std::max(lines(row.local, width, 0.004f, fw), lines(plank.local, length, 0.004f, fw));
  return mix(a, 0.18f, gaps);
}

float ceiling_tiles(float u, float v, float fw, std::uint32_t seed) {
  const float size = 0.6f;
  const Cell cu = cell(u, size), cv = cell(v, size);
  float a = 0.78f;
  if (hash01(cu.index, cv.index, seed) < 0.07f) a = 0.62f;  // a stained tile
  a *= 1.0f - 0.18f * smoothstep(0.65f, 0.8f, band_noise(u, v, 90.0f, 90.0f, fw, 0.0f, 0.0f));
  return mix(a, 0.88f, std::max(lines(u, size, 0.024f, fw), lines(v, size, 0.024f, fw)));
}

float bookshelf(float u, float v, float fw, std::uint32_t seed) {
  const float row_height = 0.4f;
  const Cell row = cell(v, row_height);
  const float board = periodic_box(row.local, 0.0f, 0.025f, row_height, fw);
  const float slot_width = 0.032f;
  const Cell slot = cell(u, slot_width);
  // A book covers one or two slots: pair slots whose hash says so.
  const int book = slot.index - (hash01(slot.index, row.index, seed) < 0.3f ? 1 : 0);
  const float h = hash01(book, row.index, seed + 1u);
  const bool empty = h < 0.08f;
  const float top = 0.025f + 0.2f + 0.15f * hash01(book, row.index, seed + 2u);
  const float variation = cell_variation(slot_width, fw);
  const float spine = empty ? 0.06f : mix(0.5f, 0.08f + 0.82f * h, variation);
  const float books = periodic_box(row.local, 0.025f, top, row_height, fw);
  float a = mix(0.08f, spine, books);  // dark back panel above the books
  if (!empty && h > 0.5f)  // a label on the spine
    a = mix(a, 0.85f, variation * periodic_box(row.local, 0.12f, 0.15f, row_height, fw));
  a = mix(a, 0.05f, variation * lines(slot.local, slot_width, 0.003f, fw) * books);
  return mix(a, 0.55f, board);
}

float cabinet(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.56f * (0.92f + 0.16f * band_noise(u, v, 2.0f, 30.0f, fw, 3.0f, 1.0f));
  const float door = 0.5f;
  const Cell c = cell(u, door);
  a = mix(a, 0.14f, std::max(lines(u, door, 0.006f, fw), box1(v, 0.08f, 0.09f, fw)));
  a = mix(a, 0.25f, box1(v, -10.0f, 0.08f, fw));  // plinth
  const bool left = (c.index & 1) != 0;
  const float hu = left ? 0.04f : door - 0.06f;
  a = mix(a, 0.85f, rect(c.local, v, hu, hu + 0.02f, 0.55f, 0.7f, fw));  // handle
  (void)seed;
  return a;
}

float fabric(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.34f + 0.1f * (fbm(u, v, 1.5f, 3, fw, seed) - 0.5f);
  a *= 0.92f + 0.16f * band_noise(u, v, 110.0f, 110.0f, fw, 0.0f, 0.0f);
  return mix(a, 0.18f, std::max(lines(u, 0.6f, 0.008f, fw), lines(v, 0.45f, 0.008f, fw)));
}

float table_top(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.58f * (0.88f + 0.24f * band_noise(u, v, 1.5f, 45.0f, fw, 2.0f, 3.0f));
  // Sheets of paper and a notebook on the top face.
  for (int i = 0; i < 3; ++i) {
    const float pu = -0.5f + 0.9f * hash01(i, 1, seed), pv = -0.3f + 0.5f * hash01(i, 2, seed);
    const float paper = rect(u, v, pu, pu + 0.21f, pv, pv + 0.297f, fw);
    if (paper > 0.0f) {
      const float print = lines(v - pv, 0.012f, 0.004f, fw) * box1(u - pu, 0.02f, 0.19f, fw) *
                          box1(v - pv, 0.03f, 0.26f, fw);
      a = mix(a, mix(0.9f, 0.3f, print), paper);
    }
  }
  return a;
}

float windows_facade(float u, float v, float fw, std::uint32_t seed, float wall) {
  const float bay = 3.6f, storey = 3.2f;
  const Cell cu = cell(u, bay), cv = cell(v, storey);
  const bool ground = cv.index == 0;
  const float u0 = 1.0f, u1 = 2.6f;
  const float v0 = ground ? 0.0f : 0.9f, v1 = ground ? 2.3f : 2.5f;
  const bool door = ground && hash01(cu.index, 0, seed) < 0.35f;
  const float uu0 = door ? 1.3f : u0, uu1 = door ? 2.3f : u1;
  const float vv0 = door ? 0.0f : (ground ? 0.6f : v0);
  const float outer = rect(cu.local, cv.local, uu0, uu1, vv0, v1, fw);
  float a = wall;
  a = mix(a, 0.75f, (ground ? 0.0f : 1.0f) * rect(cu.local, cv.local, u0 - 0.08f, u1 + 0.08f, v0 - 0.1f, v0, fw));  // sill
  if (outer > 0.0f) {
    const float inner = rect(cu.local, cv.local, uu0 + 0.06f, uu1 - 0.06f, vv0 + 0.06f, v1 - 0.06f, fw);
    const float mullion = box1(cu.local, 0.5f * (uu0 + uu1) - 0.03f, 0.5f * (uu0 + uu1) + 0.03f, fw);
    float glass = 0.035f;
    const float h = hash01(cu.index, cv.index, seed);
    if (door) glass = 0.22f + 0.1f * h;
    else if (h < 0.25f) glass = 0.28f + 0.2f * band_noise(cu.local, cv.local, 6.0f, 1.0f, fw, h * 9.0f, 0.0f);  // curtains
    a = mix(a, mix(0.72f, mix(glass, 0.72f, mullion), inner), outer);
  }
  return a;
}

float brick(float u, float v, float fw, std::uint32_t seed) {
  const float bh = 0.08f, bw = 0.24f;
  const Cell row = cell(v, bh);
  const Cell col = cell(u + ((row.index & 1) ? 0.5f * bw : 0.0f), bw);
  float a = 0.46f + 0.16f * cell_variation(bh, fw) * (hash01(col.index, row.index, seed) - 0.5f);
  a *= 0.9f + 0.2f * fbm(u, v, 3.0f, 3, fw, seed);
  a = mix(a, 0.58f, std::max(lines(row.local, bh, 0.011f, fw), lines(col.local, bw, 0.011f, fw)));
  a *= 0.85f + 0.15f * fbm(u, v, 0.3f, 2, fw, seed + 3u);  // weathering
  return windows_facade(u, v, fw, seed, a);
}

float plaster(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.62f + 0.18f * (fbm(u, v, 0.5f, 5, fw, seed) - 0.5f);
  a *= 1.0f - 0.3f * smoothstep(0.6f, 0.8f, band_noise(u, v, 1.5f, 0.2f, fw, 1.0f, 2.0f));
  a = mix(a, 0.4f, box1(v, -10.0f, 0.5f, fw));  // plinth
  return windows_facade(u, v, fw, seed, a);
}

float vegetation(float u, float v, float fw, std::uint32_t seed) {
  const float o = static_cast<float>(seed & 255u);
  const float n = 0.45f * band_noise(u, v, 6.0f, 6.0f, fw, o, 0.0f) +
                  0.35f * band_noise(u, v, 19.0f, 19.0f, fw, 0.0f, o) +
                  0.2f * band_noise(u, v, 53.0f, 53.0f, fw, o, o);
  return 0.2f + 0.5f * smoothstep(0.35f, 0.65f, n);
}

float paving(float u, float v, float fw, std::uint32_t seed) {
  const float size = 0.4f;
  const Cell cu = cell(u, size), cv = cell(v, size);
  float a = 0.40f + 0.12f * cell_variation(size, fw) * (hash01(cu.index, cv.index, seed) - 0.5f);
  a *= 0.9f + 0.2f * band_noise(u, v, 25.0f, 25.0f, fw, 0.0f, 0.0f);
  return mix(a, 0.2f, std::max(lines(u, size, 0.008f, fw), lines(v, size, 0.008f, fw)));
}

float street(float u, float v, float fw, std::uint32_t seed) {
  using namespace layout;
  const float dx = std::max(std::fabs(u) - kBlockHalfX, 0.0f);
  const float dy = std::max(std::fabs(v) - kBlockHalfY, 0.0f);
  const float d = std::sqrt(dx * dx + dy * dy);
  if (d < kInnerPavement - 0.15f) return paving(u, v, fw, seed);
  if (d > kRoadOuter + 0.15f) {
    float a = paving(u, v, fw, seed + 1u);
    const Cell strip = cell(dx > dy ? v : u, 5.0f);
    if (d > 9.0f && d < 10.3f && hash01(strip.index, 0, seed) < 0.55f)  // grass verges
      a = mix(a, vegetation(u, v, fw, seed), box1(d, 9.0f, 10.3f, fw) * box1(strip.local, 0.3f, 4.7f, fw));
    return a;
  }
  float a = 0.11f + 0.08f * (fbm(u, v, 0.4f, 3, fw, seed) - 0.5f);
  a *= 0.8f + 0.4f * band_noise(u, v, 60.0f, 60.0f, fw, 2.0f, 2.0f);  // aggregate
  const Cell pu = cell(u, 4.0f), pv = cell(v, 3.0f);
  if (hash01(pu.index, pv.index, seed) < 0.15f)  // a patch of newer asphalt
    a = mix(a, 0.07f, rect(pu.local, pv.local, 0.4f, 3.1f, 0.3f, 2.4f, fw));
  a = mix(a, 0.55f, box1(d, kInnerPavement - 0.15f, kInnerPavement + 0.02f, fw));  // kerb stones
  a = mix(a, 0.55f, box1(d, kRoadOuter - 0.02f, kRoadOuter + 0.15f, fw));
  const float along = dx > 0.0f ? v : u;
  const Cell dash = cell(along, 6.0f);
  a = mix(a, 0.72f, box1(d, kLaneCentre - 0.06f, kLaneCentre + 0.06f, fw) * box1(dash.local, 0.0f, 3.0f, fw));
  a = mix(a, 0.72f, box1(d, kRoadOuter - 0.45f, kRoadOuter - 0.33f, fw));  // edge line
  if (dx == 0.0f && std::fabs(u - 6.0f) < 2.2f)  // a zebra crossing on the long sides
    a = mix(a, 0.7f, lines(v, 1.0f, 0.5f, fw) * box1(u, 4.0f, 8.0f, fw) * box1(d, kInnerPavement, kRoadOuter, fw));
  return a;
}

float parking_floor(float u, float v, float fw, std::uint32_t seed) {
  using namespace layout;
  float a = 0.34f + 0.12f * (fbm(u, v, 0.5f, 3, fw, seed) - 0.5f);
  a *= 0.88f + 0.24f * band_noise(u, v, 35.0f, 35.0f, fw, 1.0f, 1.0f);
  const float ay = std::fabs(v);
  const bool in_bays = (ay > kCarRowInner && ay < kCarRowOuter) || (ay > kOuterCarsFrom && ay < kOuterCarsTo);
  const float within_x = box1(u, -kCarsHalfX - 0.6f, kCarsHalfX + 0.6f, fw);
  if (in_bays) {
    a *= 1.0f - 0.3f * smoothstep(0.6f, 0.8f, fbm(u, v, 0.9f, 2, fw, seed + 2u));  // oil stains
    a = mix(a, 0.78f, lines(u, kBayWidth, 0.12f, fw) * within_x);
  }
  // Bay end lines along the aisles.
  const float ends = box1(ay, kCarRowOuter - 0.12f, kCarRowOuter, fw) + box1(ay, kOuterCarsFrom, kOuterCarsFrom + 0.12f, fw);
  a = mix(a, 0.78f, clamp01(ends) * within_x);
  // Tyre tracks in the aisles, a dashed centre line and arrows every 16 m.
  const float track = std::min(std::fabs(ay - static_cast<float>(kAisleY) - 0.8f), std::fabs(ay - static_cast<float>(kAisleY) + 0.8f));
  a *= 1.0f - 0.25f * clamp01(1.0f - track / 0.35f) * band_noise(u, v, 0.3f, 4.0f, fw, 3.0f, 0.0f);
  const Cell dash = cell(u, 4.0f);
  a = mix(a, 0.7f, box1(ay, static_cast<float>(kAisleY) - 0.05f, static_cast<float>(kAisleY) + 0.05f, fw) * box1(dash.local, 0.0f, 2.0f, fw));
  const Cell arrow = cell(u, 16.0f);
  const float side = ay - static_cast<float>(kAisleY);
  const float shaft = rect(arrow.local, side, 6.0f, 7.6f, -1.2f, -1.0f, fw);
  const float head = rect(arrow.local, side, 7.6f, 7.8f, -1.45f, -0.75f, fw) + rect(arrow.local, side, 7.8f, 8.0f, -1.3f, -0.9f, fw) +
                     rect(arrow.local, side, 8.0f, 8.2f, -1.17f, -1.03f, fw);
  a = mix(a, 0.75f, clamp01(shaft + head));
  return a;
}

float pillar(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.62f + 0.1f * (fbm(u, v, 1.0f, 4, fw, seed) - 0.5f);
  a *= 1.0f - 0.3f * smoothstep(0.7f, 0.9f, band_noise(u, v, 3.0f, 0.6f, fw, 2.0f, 0.0f));  // scrapes
  // Hazard stripes at the foot.
  const float diag = u + v;
  const Cell s = cell(diag, 0.2f);
  const float stripe = mix(box1(s.local, 0.0f, 0.1f, fw), 0.5f, clamp01((fw / 0.2f - 0.25f) * 4.0f));
  a = mix(a, mix(0.72f, 0.07f, stripe), box1(v, -10.0f, 1.0f, fw));
  a = mix(a, 0.07f, box1(v, 1.0f, 1.05f, fw));
  // A band with the bay number: glyphs on white.
  const float band = box1(v, 1.5f, 1.9f, fw);
  if (band > 0.0f) {
    const float ink = blocks(u, v - 1.55f, 0.06f, fw, seed + 9u, 0.0f, 1.0f);
    const float glyph = box1(v, 1.56f, 1.84f, fw) * (ink > 0.55f ? 1.0f : 0.0f);
    a = mix(a, mix(0.85f, 0.08f, glyph * cell_variation(0.06f, fw)), band);
  }
  return a;
}

// NIR reflectance of car paint: carbon-black paints are dark at 850 nm, most others fairly bright.
float car_paint(std::uint32_t seed) {
  const float h = hash01(static_cast<int>(seed), 17, 99u);
  return h < 0.3f ? 0.04f + 0.3f * h : 0.25f + 0.5f * (h - 0.3f) / 0.7f;
}

float car_body(float u, float v, float fw, std::uint32_t seed) {
  float a = car_paint(seed) * (0.92f + 0.16f * fbm(u, v, 2.0f, 2, fw, seed));
  a = mix(a, 0.06f, lines(u, 1.1f, 0.006f, fw));  // door and panel seams
  a = mix(a, 0.75f, lines(u + 0.3f, 1.1f, 0.12f, fw) * box1(v, 0.72f, 0.76f, fw));  // handles
  return a;
}

float car_window(float u, float v, float fw, std::uint32_t seed) {
  const float glass = 0.04f + 0.04f * band_noise(u, v, 3.0f, 3.0f, fw, 0.0f, 0.0f);
  return mix(glass, car_paint(seed), std::max(lines(u, 1.2f, 0.09f, fw), box1(v, 1.38f, 10.0f, fw)));
}

float metal(float u, float v, float fw, std::uint32_t seed) {
  float a = 0.52f + 0.1f * (fbm(u, v, 4.0f, 3, fw, seed) - 0.5f);
  a *= 0.9f + 0.2f * band_noise(u, v, 40.0f, 3.0f, fw, 0.0f, 0.0f);
  return a;
}

float pipe_steel(float u, float v, float fw, std::uint32_t seed) {
  const float paint = 0.3f + 0.4f * hash01(static_cast<int>(seed & 0xFFFF), 5, 7u);
  float a = paint * (0.9f + 0.2f * fbm(u, v, 2.0f, 3, fw, seed));
  const Cell flange = cell(v, 6.0f);
  a = mix(a, 0.7f, box1(flange.local, 0.0f, 0.06f, fw));
  a = mix(a, 0.1f, box1(flange.local, 2.9f, 3.5f, fw) * box1(u, -0.1f, 0.1f, fw));  // a label band
  return a;
}

float lamp(float u, float v, float fw, std::uint32_t seed) {
  (void)seed;
  return mix(0.82f, 0.2f, std::max(lines(u, 0.3f, 0.02f, fw), lines(v, 0.3f, 0.02f, fw)));
}

}  // namespace

float value_noise(float x, float y) { return noise(x, y); }

float material_albedo(Material material, float u, float v, float footprint, std::uint32_t seed) {
  const float fw = footprint;
  switch (material) {
    case Material::PaintedWall: return painted_wall(u, v, fw, seed);
    case Material::Concrete: return concrete(u, v, fw, seed);
    case Material::TunnelLining: return tunnel_lining(u, v, fw, seed);
    case Material::FloorTiles: return floor_tiles(u, v, fw, seed);
    case Material::WoodFloor: return wood_floor(u, v, fw, seed);
    case Material::CeilingTiles: return ceiling_tiles(u, v, fw, seed);
    case Material::Bookshelf: return bookshelf(u, v, fw, seed);
    case Material::Cabinet: return cabinet(u, v, fw, seed);
    case Material::Fabric: return fabric(u, v, fw, seed);
    case Material::TableTop: return table_top(u, v, fw, seed);
    case Material::Brick: return brick(u, v, fw, seed);
    case Material::Plaster: return plaster(u, v, fw, seed);
    case Material::Street: return street(u, v, fw, seed);
    case Material::Vegetation: return vegetation(u, v, fw, seed);
    case Material::ParkingFloor: return parking_floor(u, v, fw, seed);
    case Material::Pillar: return pillar(u, v, fw, seed);
    case Material::CarBody: return car_body(u, v, fw, seed);
    case Material::CarWindow: return car_window(u, v, fw, seed);
    case Material::Metal: return metal(u, v, fw, seed);
    case Material::Rubber: return 0.05f + 0.02f * band_noise(u, v, 8.0f, 1.0f, fw, 0.0f, 0.0f);
    case Material::PipeSteel: return pipe_steel(u, v, fw, seed);
    case Material::Lamp: return lamp(u, v, fw, seed);
  }
  return 0.3f;
}

}  // namespace nirslam::sim
