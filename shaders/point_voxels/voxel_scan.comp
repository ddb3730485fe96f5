#version 450
// The cell ranges of eq. 1's sorted order: start[k] = sum of the counts of the cells before k
// (exclusive scan), start[cells] = the proxy count; the occupied cells and the largest count to the
// status. One workgroup: each invocation scans a contiguous run of cells, the runs' totals are
// scanned in shared memory.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvScanGroup) in;
layout(std430, set = 0, binding = kPvScanBindCount) readonly buffer Count { uint count[]; };
layout(std430, set = 0, binding = kPvScanBindStart) writeonly buffer Start { uint start[]; };
layout(std430, set = 0, binding = kPvScanBindStatus) buffer Status { uint status[]; };

shared uint run_total[kPvScanGroup];

void main() {
  const uint cells = uint(g_dims.w), t = gl_LocalInvocationID.x;
  const uint per = (cells + kPvScanGroup - 1u) / kPvScanGroup;
  const uint b = min(cells, t * per), e = min(cells, b + per);
  uint sum = 0u, occupied = 0u, largest = 0u;
  for (uint k = b; k < e; ++k) {
    sum += count[k];
    occupied += count[k] > 0u ? 1u : 0u;
    largest = max(largest, count[k]);
  }
  run_total[t] = sum;
  barrier();
  // Hillis-Steele inclusive scan of the run totals.
  for (uint off = 1u; off < kPvScanGroup; off <<= 1) {
    const uint add = t >= off ? run_total[t - off] : 0u;
    barrier();
    run_total[t] += add;
    barrier();
  }
  uint acc = run_total[t] - sum;
  for (uint k = b; k < e; ++k) {
    start[k] = acc;
    acc += count[k];
  }
  if (t == kPvScanGroup - 1u) start[cells] = run_total[t];
  if (occupied > 0u) atomicAdd(status[kPvStatusCount], occupied);
  if (largest > 0u) atomicMax(status[kPvStatusLargest], largest);
}
