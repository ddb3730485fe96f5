// The display G-buffer's planes as the Vulkan "gbuffer" pass leaves them on the device, beside the
// host copy it reads back: a later GPU pass of the same frame binds them instead of packing and
// uploading the host planes again (the eq. 11 weights read each display pixel's normal and depth,
// the direct shading of display pixels their positions and normals).
// The pass stores this as the device copy of render::kGBuffer (FrameContext::put_device).
#pragma once

#include <glm/glm.hpp>

namespace softgi::backends::vulkan {

class Buffer;

struct DeviceGBuffer {
  // One RGBA32F texel per pixel, row-major: the normal (xyz) and the eye depth (w) of the host
  // copy's normal and depth planes, bit for bit; background pixels hold depth +inf.
  const Buffer* normal_depth = nullptr;
  // The same for the position (xyz) and the eye depth (w).
  const Buffer* position_depth = nullptr;
  int width = 0, height = 0;
  // The host copy these planes belong to: a pass given planes at other addresses (another buffer,
  // or the planes copied) uploads them as before.
  const float* host_depth = nullptr;
  const glm::vec3* host_normal = nullptr;
  const glm::vec3* host_position = nullptr;
};

}  // namespace softgi::backends::vulkan
