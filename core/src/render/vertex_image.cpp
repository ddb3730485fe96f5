#include "softgi/render/vertex_image.hpp"

#include "vertex_image_run.hpp"

#include <algorithm>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace softgi::render {

namespace {

// environment_background's callable, a type of its own so that background_run recognises it
// (std::function::target) and evaluates a run of directions at once.
struct EnvironmentBackground {
  scene::EnvironmentRadiance eval;
  glm::vec3 operator()(const glm::vec3& d) const { return eval(d); }
};

// background(dir[k]) into out[k], k < n: the environment's directions all at once.
void background_along(const BackgroundFn& background, const glm::vec3* dir, int n, glm::vec3* out) {
  if (const auto* env = background.target<EnvironmentBackground>()) {
    env->eval(dir, static_cast<std::size_t>(n), out);
    return;
  }
  for (int k = 0; k < n; ++k) out[k] = background(dir[k]);
}

}  // namespace

Image interpolate_vertex_values(const GBuffer& gb, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex, const BackgroundFn& background) {
  return interpolate_vertex_values(gb, posed, per_vertex, background, Image(), false);
}

Image interpolate_vertex_values(const GBuffer& gb, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex, const BackgroundFn& background,
                                Image storage, bool times_albedo) {
  return interpolate_vertex_values(gb, posed, per_vertex, background, std::move(storage), times_albedo, DerivedPlanes{});
}

Image interpolate_vertex_values(const GBuffer& gb, const scene::PosedScene& posed,
                                const std::vector<std::vector<glm::vec3>>& per_vertex, const BackgroundFn& background,
                                Image storage, bool times_albedo, const DerivedPlanes& derive) {
  const std::size_t n = static_cast<std::size_t>(gb.width) * gb.height;
  const bool own_dir = gb.view_dir.size() != n && derive.camera;
  const bool own_albedo = times_albedo && gb.albedo.size() != n && derive.scene;
  if (gb.width < 0 || gb.height < 0 || gb.object.size() != n || gb.primitive.size() != n || gb.barycentric.size() != n ||
      (gb.view_dir.size() != n && !own_dir) || (times_albedo && gb.albedo.size() != n && !own_albedo))
    throw std::invalid_argument("interpolate_vertex_values: G-buffer of " + std::to_string(gb.width) + "x" +
                                std::to_string(gb.height) + " has incomplete object/primitive/barycentric/view_dir" +
                                (times_albedo ? "/albedo" : "") + " planes and none is derived");
  // The checks a visible pixel needs, made where the loop reads it (one pass over the G-buffer): its
  // object, that object's mesh and per-vertex values (once per run of pixels of one object), its
  // triangle. Objects no pixel sees need no values.
  auto check_object = [&](std::size_t i, int o) {
    if (o >= static_cast<int>(posed.objects.size()))
      throw std::invalid_argument("interpolate_vertex_values: pixel " + std::to_string(i) + " sees object " +
                                  std::to_string(o) + " but the posed scene has " + std::to_string(posed.objects.size()));
    const scene::PosedObject& obj = posed.objects[o];
    const std::string name = obj.source ? "'" + obj.source->name + "'" : std::to_string(o);
    if (!obj.source) throw std::invalid_argument("interpolate_vertex_values: object " + name + " has no mesh");
    if (o >= static_cast<int>(per_vertex.size()) || per_vertex[o].size() < obj.positions.size())
      throw std::invalid_argument("interpolate_vertex_values: object " + name + " (index " + std::to_string(o) +
                                  ") is visible but has " +
                                  std::to_string(o < static_cast<int>(per_vertex.size()) ? per_vertex[o].size() : 0) +
                                  " per-vertex values for " + std::to_string(obj.positions.size()) + " vertices");
  };

  Image out = std::move(storage);
  out.width = gb.width;
  out.height = gb.height;
  out.rgb.resize(n);  // every pixel is written below
  // The camera rays of the buffer's columns and rows, for background pixels whose direction is derived.
  std::optional<BufferRays> rays;
  if (own_dir && background) rays.emplace(*derive.camera, gb.width, gb.height, gb.scale);
  tbb::parallel_for(tbb::blocked_range<int>(0, gb.height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<glm::vec3> dirs;  // a run's derived ray directions
    int checked = -1;
    bool uniform = false;  // the checked object's albedo is the same everywhere: `albedo`
    glm::vec3 albedo(0.0f);
    for (int y = rows.begin(); y != rows.end(); ++y) {
      const std::size_t row0 = static_cast<std::size_t>(y) * gb.width;
      // Runs of pixels that see one object (or none), each interpolated in vector lanes.
      for (int x = 0; x < gb.width;) {
        const std::size_t i = row0 + x;
        const int o = gb.object[i];
        const int x1 = object_run_end(&gb.object[row0], x, gb.width);
        const int run = x1 - x;
        if (o < 0) {
          if (!background) {
            std::fill_n(out.rgb.begin() + static_cast<std::ptrdiff_t>(i), run, glm::vec3(0.0f));
          } else if (own_dir) {
            background_run(background, *derive.camera, *rays, x, y, run, &out.rgb[i], dirs);  // the G-buffer's rays
          } else {
            // The G-buffer's rays (its view_dir for background pixels).
            background_along(background, &gb.view_dir[i], run, &out.rgb[i]);
          }
          x = x1;
          continue;
        }
        if (o != checked) {
          check_object(i, o);
          checked = o;
          uniform = own_albedo && scene::constant_albedo(*derive.scene, posed.objects[o], albedo);
        }
        const scene::Mesh& mesh = *posed.objects[o].source;
        // Albedo per pixel from the G-buffer's plane, or derived (below) where it is not uniform.
        const bool plane_albedo = times_albedo && !own_albedo;
        if (!detail::interpolate_run(mesh.triangles.data(), static_cast<int>(mesh.triangles.size()), per_vertex[o].data(),
                                     &gb.primitive[i], &gb.barycentric[i], run, plane_albedo ? &gb.albedo[i] : nullptr,
                                     times_albedo && uniform, albedo, &out.rgb[i])) {
          for (int k = 0; k < run; ++k) {
            const int t = gb.primitive[i + k];
            if (t < 0 || t >= static_cast<int>(mesh.triangles.size()))
              throw std::invalid_argument("interpolate_vertex_values: pixel " + std::to_string(i + k) + " has primitive " +
                                          std::to_string(t) + " outside mesh '" + mesh.name + "'");
          }
        }
        if (times_albedo && own_albedo && !uniform)
          for (int k = 0; k < run; ++k) {
            const glm::vec2 b = gb.barycentric[i + k];
            out.rgb[i + k] *= scene::surface_albedo(*derive.scene, posed.objects[o], static_cast<std::size_t>(gb.primitive[i + k]), b.x, b.y);
          }
        x = x1;
      }
    }
  });
  return out;
}

void background_run(const BackgroundFn& background, const PinholeCamera& camera, const BufferRays& rays, int x0, int y, int n,
                    glm::vec3* out, std::vector<glm::vec3>& scratch) {
  if (n <= 0) return;
  scratch.resize(static_cast<std::size_t>(n));
  detail::ray_directions(camera.forward, camera.right, camera.up, &rays.sx[static_cast<std::size_t>(x0)],
                         rays.sy[static_cast<std::size_t>(y)], n, scratch.data());
  background_along(background, scratch.data(), n, out);
}

int object_run_end(const std::int32_t* object, int x, int width) {
  const std::int32_t o = object[x];
  int x1 = x + 1;
  // Sixteen at a time while all sixteen match (a loop of fixed length: vector compares), then one
  // at a time.
  while (x1 + 16 <= width) {
    int differ = 0;
    for (int k = 0; k < 16; ++k) differ |= object[x1 + k] != o ? 1 : 0;
    if (differ) break;
    x1 += 16;
  }
  while (x1 < width && object[x1] == o) ++x1;
  return x1;
}

glm::vec3 background_radiance(const scene::Environment& env, const glm::vec3& ray_dir) { return env.radiance(ray_dir); }

BackgroundFn environment_background(const scene::Environment& env) {
  // Prepared once: per pixel, Environment::radiance would work out the sun's direction and the
  // cosines again.
  return EnvironmentBackground{scene::EnvironmentRadiance(env)};
}

}  // namespace softgi::render
