// Scalar reads of texel buffers (vk::Bind::texels_at), for shaders that read many: one component
// of texel i of a one-component view.
#ifndef SOFTGI_TEXELS_GLSL
#define SOFTGI_TEXELS_GLSL
float texel1(samplerBuffer b, uint i) { return texelFetch(b, int(i)).x; }
uint texel1(usamplerBuffer b, uint i) { return texelFetch(b, int(i)).x; }
#endif
