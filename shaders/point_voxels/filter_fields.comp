#version 450
// The visibility filter's window and constraints (eq. 4) applied to the escaped rays' sky light:
// the mean over the accepted neighbours (filter_field). One invocation per marching pixel.
#extension GL_GOOGLE_include_directive : require
#include "pv_shared.h"
#include "pv_common.glsl"

layout(local_size_x = kPvGroup) in;
layout(std430, set = 0, binding = kPvFiltBindPixels) readonly buffer Pixels { MarchPixel pixels[]; };
layout(std430, set = 0, binding = kPvFiltBindIn) readonly buffer In { vec4 fields_in[]; };
layout(std430, set = 0, binding = kPvFiltBindOut) writeonly buffer Out { vec4 fields_out[]; };
layout(push_constant) uniform Push {
  uint first, end;
  int width, height;
  uint words;
  int radius_x, radius_y;
  float depth_threshold, normal_threshold;
} pc;

void main() {
  const uint p = pc.first + gl_GlobalInvocationID.x;
  if (p >= pc.end) return;
  const MarchPixel mp = pixels[p];
  if (mp.pos_hit.w == 0.0) {
    fields_out[p] = vec4(0.0);
    return;
  }
  const int x = int(p % uint(pc.width)), y = int(p / uint(pc.width));
  const float zp = mp.normal_depth.w;
  vec4 sum = vec4(0.0);
  int n = 0;
  for (int j = max(0, y - pc.radius_y); j <= min(pc.height - 1, y + pc.radius_y); ++j)
    for (int i = max(0, x - pc.radius_x); i <= min(pc.width - 1, x + pc.radius_x); ++i) {
      const uint q = uint(j) * uint(pc.width) + uint(i);
      if (q != p) {
        const MarchPixel mq = pixels[q];
        if (mq.pos_hit.w == 0.0) continue;
        if (!(abs(mq.normal_depth.w - zp) <= pc.depth_threshold * zp && dot(mp.normal_depth.xyz, mq.normal_depth.xyz) >= pc.normal_threshold))
          continue;
      }
      sum += fields_in[q];
      ++n;
    }
  fields_out[p] = sum / float(n);
}
