#version 450
// Eq. 1's sort on the device: the (key, sampling index) pairs in ascending order by Batcher's bitonic
// network, so that each cell's proxies keep their sampling order, as the CPU's stable sort leaves
// them, and the order (with every sum over a cell after it) is the same from run to run. The keys
// are padded to a power of two N >= kBlock with (~0, ~0), which sort last.
// The network: for k = 2, 4, ..., N and j = k / 2, ..., 1, the keys lo and lo + j (lo with bit j
// clear) are put in ascending order where lo & k is 0 and descending otherwise. Steps whose pairs
// cross a block (j >= kBlock) are one dispatch each (push j > 0); the others are run by each
// workgroup on its own block in shared memory (push j = 0): every step of k = 2 ... kBlock when k is
// 0, else the steps j = kBlock / 2 ... 1 of merge k. Each invocation takes kPvSortPairs pairs per
// step, so that a block holds 2048 keys (16 KiB of shared memory) and fewer steps cross blocks.
// Every loop has a fixed trip count (the loop limits in docs/backends.md).
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"

layout(local_size_x = kPvSortGroup) in;
layout(std430, set = 0, binding = kPvSortBindPairs) buffer Pairs { uvec2 keys[]; };
layout(push_constant) uniform Push { uint k, j; } pc;

const uint kBlock = 2u * kPvSortGroup * kPvSortPairs;
shared uvec2 block[kBlock];

bool before(uvec2 a, uvec2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); }

// The lower key of the p-th pair at distance j: p with a 0 bit inserted at j's place.
uint pair_lo(uint p, uint j) { return ((p & ~(j - 1u)) << 1u) | (p & (j - 1u)); }

void main() {
  const uint t = gl_LocalInvocationID.x;
  if (pc.j > 0u) {
    for (uint q = 0u; q < kPvSortPairs; ++q) {
      const uint lo = pair_lo(gl_WorkGroupID.x * (kBlock / 2u) + q * kPvSortGroup + t, pc.j), hi = lo + pc.j;
      const uvec2 a = keys[lo], b = keys[hi];
      if (before(b, a) == ((lo & pc.k) == 0u)) {
        keys[lo] = b;
        keys[hi] = a;
      }
    }
    return;
  }
  const uint base = gl_WorkGroupID.x * kBlock;
  for (uint q = 0u; q < 2u * kPvSortPairs; ++q) block[q * kPvSortGroup + t] = keys[base + q * kPvSortGroup + t];
  barrier();
  const uint k_first = pc.k == 0u ? 2u : pc.k, k_last = pc.k == 0u ? kBlock : pc.k;
  for (uint k = k_first; k <= k_last; k <<= 1u)
    for (uint j = min(k >> 1u, kBlock / 2u); j > 0u; j >>= 1u) {
      for (uint q = 0u; q < kPvSortPairs; ++q) {
        const uint lo = pair_lo(q * kPvSortGroup + t, j), hi = lo + j;
        const uvec2 a = block[lo], b = block[hi];
        // The direction by the key's place in the whole array, as the dispatched steps take it.
        if (before(b, a) == (((base + lo) & k) == 0u)) {
          block[lo] = b;
          block[hi] = a;
        }
      }
      barrier();
    }
  for (uint q = 0u; q < 2u * kPvSortPairs; ++q) keys[base + q * kPvSortGroup + t] = block[q * kPvSortGroup + t];
}
