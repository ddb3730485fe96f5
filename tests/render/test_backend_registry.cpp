// The backend registry, the order in which a backend finds a pass's implementation, and the
// stepped frame the parity tests run pass by pass.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;

namespace {

class NamedBackend : public render::Backend {
 public:
  explicit NamedBackend(std::string n) : n_(std::move(n)) {}
  std::string name() const override { return n_; }

 private:
  std::string n_;
};

render::BackendInfo info(const std::string& name, std::string why = "", bool device = false) {
  render::BackendInfo b;
  b.name = name;
  b.description = "test backend " + name;
  b.selects_device = device;
  b.unavailable = [why] { return why; };
  b.create = [name](const render::BackendOptions&) -> std::unique_ptr<render::Backend> { return std::make_unique<NamedBackend>(name); };
  return b;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(BackendRegistry, RegistersOnceAndExplainsUnknownAndUnavailableBackends) {
  render::register_backend(info("test_ok"));
  render::register_backend(info("test_missing", "no such device here"));
  render::register_backend(info("test_device", "", true));
  EXPECT_NE(error_of([] { render::register_backend(info("test_ok")); }).find("registered twice"), std::string::npos);
  EXPECT_NE(error_of([] { render::register_backend(info("")); }).find("invalid backend name"), std::string::npos);
  EXPECT_NE(error_of([] { render::register_backend(info(render::kHostImpl)); }).find("invalid backend name"), std::string::npos);

  const std::vector<std::string> names = render::backend_names();
  EXPECT_EQ(names.front(), render::reference_backend_name());  // the CPU reference, registered first
  const std::string unknown = error_of([] { render::backend_info("metal"); });
  EXPECT_NE(unknown.find("unknown backend 'metal'"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("test_ok"), std::string::npos) << "the error lists the registered backends: " << unknown;

  EXPECT_EQ(render::create_backend("test_ok")->name(), "test_ok");
  const std::string missing = error_of([] { render::create_backend("test_missing"); });
  EXPECT_NE(missing.find("unavailable here: no such device here"), std::string::npos) << missing;
  render::BackendOptions o;
  o.device = "0";
  const std::string nodev = error_of([&] { render::create_backend("test_ok", o); });
  EXPECT_NE(nodev.find("selects no device"), std::string::npos) << nodev;
  EXPECT_EQ(render::create_backend("test_device", o)->name(), "test_device");
}

TEST(BackendRegistry, APassRunsItsBackendsImplementationThenTheSharedOneThenTheHostOne) {
  int host = 0, own = 0, shared = 0;
  render::PassDesc p{"test_pass", {}, {}, {"x"}, "", {}};
  p.impl[render::kHostImpl] = [&](render::FrameContext&) { ++host; };
  p.impl["test_own"] = [&](render::FrameContext&) { ++own; };
  render::register_shared_pass_impl("test_pass", "test_shared", [&](render::FrameContext&) { ++shared; });
  const scene::Scene sc = scene::make_builtin("spheres");
  const scene::PosedScene posed = scene::evaluate(sc, 0.0);
  render::ParamSet params;
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, 4, 4, result);
  for (const char* b : {"test_own", "test_shared", "test_other", render::kHostImpl}) {
    const render::PassFn* fn = render::find_pass_impl(p, b);
    ASSERT_NE(fn, nullptr) << b;
    (*fn)(ctx);
  }
  EXPECT_EQ(own, 1);
  EXPECT_EQ(shared, 1);
  EXPECT_EQ(host, 2);  // test_other and the host itself
  render::PassDesc device_only{"device_only", {}, {}, {"y"}, "", {}};
  device_only.impl["test_own"] = [](render::FrameContext&) {};
  EXPECT_EQ(render::find_pass_impl(device_only, "test_other"), nullptr);
}

namespace {
// Two passes, the second reading the first's output: a stepped frame runs them in order and
// records them; a pass outside the requested outputs is not in its list.
class TwoPasses final : public render::Technique {
 public:
  std::string name() const override { return "two_passes"; }
  std::string description() const override { return "test"; }
  std::vector<render::ParamDesc> params() const override { return {}; }
  render::PassGraph plan(const scene::Scene&, const render::ParamSet&, std::set<std::string>&) override {
    render::PassGraph g;
    g.add_input(render::kScene);
    g.add({"first", {render::kScene}, {}, {"a"}, "", render::host_impl([](render::FrameContext& c) { c.put<int>("a", 20); })});
    g.add({"second", {"a"}, {}, {"b"}, "",
           render::host_impl([](render::FrameContext& c) { c.put<int>("b", c.get<int>("a") + 1); })});
    g.add({"unused", {render::kScene}, {}, {"c"}, "", render::host_impl([](render::FrameContext& c) { c.put<int>("c", 0); })});
    return g;
  }
};
}  // namespace

TEST(SteppedFrame, RunsThePlannedPassesInOrderAndRecordsThem) {
  TwoPasses t;
  const scene::Scene sc = scene::make_builtin("spheres");
  render::ParamSet params;
  render::RenderRequest req;
  req.width = req.height = 4;
  req.outputs = {"b"};
  render::SteppedFrame f(t, sc, params, req);
  ASSERT_EQ(f.passes().size(), 2u);
  EXPECT_EQ(f.passes()[0]->name, "first");
  EXPECT_EQ(f.passes()[1]->name, "second");
  EXPECT_THROW(f.pass("unused"), std::invalid_argument);
  for (const render::PassDesc* p : f.passes()) f.run(*p, render::kHostImpl);
  EXPECT_EQ(f.context().get<int>("b"), 21);
  ASSERT_EQ(f.result().passes.size(), 2u);
  EXPECT_EQ(f.result().passes[1].name, "second");
  EXPECT_EQ(f.result().pruned.size(), 1u);
  f.run(f.pass("second"), render::kHostImpl, "second again");
  EXPECT_EQ(f.result().passes.back().name, "second again");
}
