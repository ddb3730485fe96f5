// Renders one small frame of every registered technique on every registered backend through the
// installed library's API, and checks that each final image is finite, non-negative and lit.
#include <cmath>
#include <cstdio>
#include <exception>
#include <softgi/backends/cpu_backend.hpp>
#include <softgi/render/backend.hpp>
#include <softgi/scene/builtin.hpp>
#include <softgi/techniques/registry.hpp>
#ifdef CONSUMER_VULKAN
#include <softgi/backends/vulkan/backend.hpp>
#endif

int main() {
  using namespace softgi;
  backends::register_cpu_backend();
  techniques::register_all();
#ifdef CONSUMER_VULKAN
  backends::register_vulkan_backend();
  techniques::register_vulkan_kernels();
#endif
  const scene::Scene sc = scene::make_builtin("spheres");
  render::RenderRequest req;
  req.width = 32;
  req.height = 24;
  int frames = 0;
  for (const auto& b : render::backend_names()) {
    const auto& info = render::backend_info(b);
    const std::string why = info.unavailable ? info.unavailable() : std::string();
    if (!why.empty()) {
      std::printf("backend %s unavailable: %s\n", b.c_str(), why.c_str());
      continue;
    }
    try {
      auto backend = render::create_backend(b);
      for (const auto& t : render::technique_names()) {
        const render::FrameResult r = render::render_frame(*backend, t, sc, nullptr, req);
        double lit = 0.0;
        for (const auto& p : r.final_image.rgb)
          for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(p[c]) || p[c] < 0.0f) {
              std::printf("%s on %s: pixel value %g\n", t.c_str(), b.c_str(), p[c]);
              return 1;
            }
            lit += p[c];
          }
        if (r.final_image.rgb.size() != 32u * 24u || !(lit > 0.0)) {
          std::printf("%s on %s: %zu pixels, sum %g\n", t.c_str(), b.c_str(), r.final_image.rgb.size(), lit);
          return 1;
        }
        std::printf("%s on %s: %zu passes, %.1f ms, upload %zu B, download %zu B\n", t.c_str(), b.c_str(), r.passes.size(),
                    r.total_seconds * 1e3, r.transfer.upload, r.transfer.download);
        ++frames;
      }
    } catch (const std::exception& e) {
      std::printf("backend %s: %s\n", b.c_str(), e.what());
      return 1;
    }
  }
  return frames > 0 ? 0 : 1;
}
