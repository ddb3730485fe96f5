// Frame warnings: what a frame leaves out that the user asked for (shadows of a scene without proxy
// spheres) or cannot do well (per-vertex receivers far coarser than the proxies that shade them).
#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <string>

#include "softgi/io/scene_file.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/pass_graph.hpp"

using namespace softgi;

namespace {

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += x + "\n";
  return s;
}

render::FrameResult frame_of(const std::string& technique, const scene::Scene& sc) {
  auto backend = render::create_backend(render::reference_backend_name());
  render::RenderRequest req;
  req.width = 24;
  req.height = 16;
  return render::render_frame(*backend, technique, sc, nullptr, req);
}

scene::Scene ball_over_floor(int floor_segments, bool proxies) {
  const std::string prox = proxies ? R"(, "proxies": [{"center": [0, 0, 0], "radius": 0.2}])" : "";
  return io::parse_scene_json(R"({"camera": {"position": [0, 2, 3], "target": [0, 0, 0]},
      "objects": [{"name": "floor", "mesh": "builtin:plane", "size": 4, "segments": )" +
                                  std::to_string(floor_segments) + R"(},
                  {"name": "ball", "mesh": "builtin:sphere", "radius": 0.2, "segments": 24,
                   "transform": {"translation": [0, 0.3, 0]})" +
                                  prox + "}]}",
                              ".", "w.json");
}

}  // namespace

TEST(FrameWarnings, GraphWarnsOnlyWhenTheResourceIsEmpty) {
  render::PassGraph g;
  g.add_input("spheres");
  g.add({"shadow", {"spheres"}, {}, {"out"}, "", render::host_impl([](render::FrameContext&) {})});
  g.warn_if_empty("spheres", "no spheres: no shadows");
  EXPECT_TRUE(g.compile({"out"}).warnings.empty());
  const render::CompiledGraph c = g.compile({"out"}, {"spheres"});
  ASSERT_EQ(c.warnings.size(), 1u);
  EXPECT_EQ(c.warnings[0], "no spheres: no shadows");
}

// A scene without proxies renders (unshadowed) with a warning naming the technique and what it left
// out; with proxies there is none.
TEST(FrameWarnings, TechniquesSayWhenTheSceneHasNoProxies) {
  for (const char* technique : {"shexp", "image_splat"}) {
    const render::FrameResult bare = frame_of(technique, ball_over_floor(64, false));
    const std::string w = joined(bare.warnings);
    EXPECT_NE(w.find("has no proxy spheres, so " + std::string(technique) + " renders it without shadows"), std::string::npos)
        << technique << ":\n"
        << w;
    EXPECT_FALSE(bare.final_image.empty());
    const render::FrameResult with = frame_of(technique, ball_over_floor(64, true));
    EXPECT_EQ(joined(with.warnings).find("no proxy spheres"), std::string::npos) << technique << ":\n" << joined(with.warnings);
  }
}

// SHEXP shades at vertices: a floor of 2 triangles (edges of 4-5.7 m) under a 0.2 m proxy cannot show
// its shadow, and the frame says so naming the floor; a 1.6 cm grid can, and the ball's own
// tessellation (about 5 cm edges) is finer than its proxy too.
TEST(FrameWarnings, ShexpWarnsAboutReceiversCoarserThanTheProxies) {
  const render::FrameResult coarse = frame_of("shexp", ball_over_floor(1, true));
  const std::string w = joined(coarse.warnings);
  EXPECT_NE(w.find("object 'floor'"), std::string::npos) << w;
  EXPECT_EQ(w.find("object 'ball'"), std::string::npos) << w;
  const render::FrameResult fine = frame_of("shexp", ball_over_floor(256, true));
  EXPECT_EQ(joined(fine.warnings).find("object 'floor'"), std::string::npos) << joined(fine.warnings);
}
