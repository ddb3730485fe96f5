#version 450
// The device's single-precision FMA peak (bench/device_peak.cpp): every invocation runs kChains
// independent fma() chains for `iterations` steps. Independent chains hide the FMA latency (4 cycles
// on x86, where llvmpipe runs a SIMD batch of invocations as one vector per chain); the result is
// written so that no chain can be optimised away.
layout(local_size_x = 64) in;
layout(std430, set = 0, binding = 0) writeonly buffer Out { float result[]; };
layout(push_constant) uniform Push {
  uint iterations;  // at most 65535: llvmpipe ends longer loops silently
  float m, c;
} pc;

void main() {
  const float seed = float(gl_GlobalInvocationID.x) * 1e-9;
  float a0 = seed, a1 = seed + 1.0, a2 = seed + 2.0, a3 = seed + 3.0, a4 = seed + 4.0, a5 = seed + 5.0, a6 = seed + 6.0,
        a7 = seed + 7.0, a8 = seed + 8.0, a9 = seed + 9.0, a10 = seed + 10.0, a11 = seed + 11.0;
  for (uint k = 0; k < pc.iterations; ++k) {
    a0 = fma(a0, pc.m, pc.c);
    a1 = fma(a1, pc.m, pc.c);
    a2 = fma(a2, pc.m, pc.c);
    a3 = fma(a3, pc.m, pc.c);
    a4 = fma(a4, pc.m, pc.c);
    a5 = fma(a5, pc.m, pc.c);
    a6 = fma(a6, pc.m, pc.c);
    a7 = fma(a7, pc.m, pc.c);
    a8 = fma(a8, pc.m, pc.c);
    a9 = fma(a9, pc.m, pc.c);
    a10 = fma(a10, pc.m, pc.c);
    a11 = fma(a11, pc.m, pc.c);
  }
  result[gl_GlobalInvocationID.x] = ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7)) + ((a8 + a9) + (a10 + a11));
}
