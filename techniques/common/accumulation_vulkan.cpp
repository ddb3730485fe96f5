#include "accumulation_vulkan.hpp"

#include "softgi/render/common_passes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace spv {
#include "softgi/shaders/common/field_column_comp.h"
}  // namespace spv

namespace softgi::techniques::common::gpu_passes {

vk::ComputePipeline& pipeline(vk::Context& dev, PipelineCache& cache, const std::string& key, std::span<const std::uint32_t> spirv,
                              const std::vector<vk::SpecConstant>& spec) {
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, std::make_unique<vk::ComputePipeline>(dev, spirv, key, spec)).first;
  return *it->second;
}

std::string mib(std::size_t bytes) {
  std::ostringstream os;
  os.precision(4);
  os << static_cast<double>(bytes) / (1024.0 * 1024.0) << " MiB";
  return os.str();
}

double timer_seconds(const vk::SubmitResult& res) { return res.timers.empty() ? -1.0 : res.timers[0].second; }

void check_fits(const vk::Context& dev, std::size_t bytes, const std::string& what, const std::string& pass, const std::string& advice) {
  const std::size_t limit = dev.device_info().limits.maxStorageBufferRange;
  if (bytes > limit)
    throw std::invalid_argument(pass + " on vulkan: " + what + " need " + mib(bytes) + ", more than the maxStorageBufferRange of " + mib(limit) +
                                " of device '" + dev.device_info().name + "' (" + advice + ")");
}

std::uint64_t content_hash(const void* data, std::size_t bytes, std::uint64_t seed) {
  // Four independent streams over 32-byte blocks, each word mixed into its own: one stream's
  // multiply-and-shift chain takes about six cycles per 8 bytes, so that a single stream hashed the
  // tens of megabytes of a display frame's inputs slower than they are copied.
  constexpr std::uint64_t kMul = 0x100000001b3ull;
  std::uint64_t h[4] = {seed ^ bytes, (seed ^ bytes) + 0x9e3779b97f4a7c15ull, (seed ^ bytes) + 0x3c6ef372fe94f82aull,
                        (seed ^ bytes) + 0xdaa66d2c7ddf743full};
  const auto* p = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 32 <= bytes; i += 32)
    for (int s = 0; s < 4; ++s) {
      std::uint64_t w;
      std::memcpy(&w, p + i + 8 * s, 8);
      h[s] = (h[s] ^ w) * kMul;
      h[s] ^= h[s] >> 29;
    }
  std::uint64_t r = h[0];
  for (int s = 1; s < 4; ++s) {
    r = (r ^ h[s]) * kMul;
    r ^= r >> 29;
  }
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t w;
    std::memcpy(&w, p + i, 8);
    r = (r ^ w) * kMul;
    r ^= r >> 29;
  }
  for (; i < bytes; ++i) r = (r ^ p[i]) * kMul;
  return r;
}

void upload_bytes_if_changed(vk::Context& dev, vk::Buffer& b, std::uint64_t& hash, const void* data, std::size_t bytes,
                             const std::string& name) {
  const VkBuffer before = b.handle();
  dev.ensure_buffer(b, std::max<std::size_t>(16, bytes), kStorage, vk::MemoryKind::Device, name);
  const std::uint64_t h = content_hash(data, bytes);
  if (b.handle() == before && h == hash) return;
  if (bytes) dev.upload(b, data, bytes);
  hash = h;
}

void upload_receivers(vk::Context& dev, vk::Buffer& buf, const ReceiverSoA& soa, const std::string& name, std::uint64_t* hash) {
  const std::size_t n = soa.size(), plane = n * sizeof(float);
  const VkBuffer before = buf.handle();
  dev.ensure_buffer(buf, std::max<std::size_t>(1, 6 * plane), kStorage, vk::MemoryKind::Device, name);
  const std::vector<float>* planes[6] = {&soa.px, &soa.py, &soa.pz, &soa.nx, &soa.ny, &soa.nz};
  std::uint64_t h = 0;
  if (hash) {
    h = 0xcbf29ce484222325ull;
    for (int a = 0; a < 6; ++a) h = content_hash(planes[a]->data(), plane, h);
    if (buf.handle() == before && h == *hash) return;
  }
  for (int a = 0; a < 6; ++a) dev.upload(buf, planes[a]->data(), plane, a * plane);
  if (hash) *hash = h;
}

OlTable upload_ol_table(vk::Context& dev, const sh::ShTables& sht, const std::string& technique) {
  const auto &xs = sht.ol_norm(), &as = sht.ol_a(), &bs = sht.ol_b();
  std::size_t m = 0;  // sh::ShTables: "keep the prefix of the sweep where the norm increases"
  while (m < xs.size() && (m == 0 || xs[m] > xs[m - 1])) ++m;
  if (m == 0) throw std::logic_error(technique + " vulkan: the OL table is empty");
  std::vector<float> ol(3 * m);
  for (std::size_t k = 0; k < m; ++k) {
    ol[k] = static_cast<float>(xs[k]);
    ol[m + k] = static_cast<float>(as[k]);
    ol[2 * m + k] = static_cast<float>(bs[k]);
  }
  return {dev.upload_vector(ol, kStorage, technique + " OL table"), static_cast<std::uint32_t>(m)};
}

void upload_if_changed(vk::Context& dev, vk::Buffer& buf, std::vector<float>& host, std::span<const float> now, const std::string& name,
                       VkBufferUsageFlags usage) {
  static const float kUnused = 0.0f;
  if (now.empty()) now = std::span<const float>(&kUnused, 1);
  if (!buf || !std::equal(host.begin(), host.end(), now.begin(), now.end())) {
    host.assign(now.begin(), now.end());
    buf = dev.upload_vector(host, usage, name);
  }
}

std::span<const std::uint32_t> order_variant(std::span<const std::uint32_t> w, int order, const std::string& what) {
  if (w.empty())
    throw std::logic_error(what + ": no shader compiled for SH order " + std::to_string(order) + " (orders 1.." +
                           std::to_string(gpu::kAccumMaxOrder) + ")");
  return w;
}

std::uint32_t loop_budget(const vk::DeviceInfo& d) {
  constexpr std::uint32_t kMargin = 4096;
  if (d.loop_iteration_limit == 0) return std::numeric_limits<std::uint32_t>::max();
  return d.loop_iteration_limit > 2 * kMargin ? d.loop_iteration_limit - kMargin : d.loop_iteration_limit / 2;
}

std::vector<float> exp_series(std::uint32_t method, int degree) {
  if (degree < 1 || degree > static_cast<int>(gpu::kExpMaxDegree))
    throw std::invalid_argument("exponentiate on vulkan: series degree " + std::to_string(degree) + " outside 1.." +
                                std::to_string(gpu::kExpMaxDegree));
  std::vector<float> h(static_cast<std::size_t>(degree) + 1, 1.0f);
  double fact = 1.0;
  for (int k = 2; k <= degree; ++k) {
    fact *= k;
    h[k] = method == gpu::kExpPs ? 1.0f / static_cast<float>(k) : static_cast<float>(1.0 / fact);
  }
  return h;
}

void exp_series_counts(std::uint32_t method, int degree, double& squares, double& products) {
  squares = products = 0.0;
  if (method == gpu::kExpPs) {
    products = std::max(0, degree - 1);
  } else if (method == gpu::kExpPsStar) {
    squares = (degree >= 2) + (degree >= 4);
    for (int k = 6; k <= degree; k += 2) products += 1.0;
    products += degree >= 3;
  }
}

PackedBlockers pack_blocker_lists(const std::vector<BlockerList>& lists, int order, std::size_t min_rows, float w_fill,
                                  const std::string& technique, const std::string& order_name) {
  const std::size_t n = static_cast<std::size_t>(order), ws = weight_stride(order);
  std::size_t total = 0;
  for (const auto& l : lists) total += l.size();
  PackedBlockers p;
  p.sph.assign(std::max(min_rows, total) * 4, 0.0f);
  p.w.assign(std::max(min_rows, total) * ws, w_fill);
  p.ranges.assign(2 * std::max(min_rows, lists.size()), 0);
  std::size_t at = 0;
  for (std::size_t li = 0; li < lists.size(); ++li) {
    const BlockerList& b = lists[li];
    if (b.size() > 0 && b.order != order)
      throw std::logic_error(technique + " vulkan: a blocker list of order " + std::to_string(b.order) + " for " + order_name + " " +
                             std::to_string(order));
    p.ranges[2 * li] = static_cast<std::uint32_t>(at);
    p.ranges[2 * li + 1] = static_cast<std::uint32_t>(b.size());
    for (std::size_t j = 0; j < b.size(); ++j, ++at) {
      p.sph[4 * at] = b.cx[j];
      p.sph[4 * at + 1] = b.cy[j];
      p.sph[4 * at + 2] = b.cz[j];
      p.sph[4 * at + 3] = b.r[j];
      if (!b.w.empty()) std::copy(b.w.begin() + j * n, b.w.begin() + (j + 1) * n, p.w.begin() + at * ws);
    }
  }
  return p;
}

std::uint32_t accumulate_log_chunk(const vk::DeviceInfo& d, int order) {
  const std::uint32_t budget = loop_budget(d);
  if (budget == std::numeric_limits<std::uint32_t>::max()) return budget;
  const std::uint32_t n = static_cast<std::uint32_t>(order);
  // The blocker loop itself, the weight vectors ((n + 3) / 4) and the band weights (n), should the
  // driver leave those two loops rolled; the basis steps are written out, no loops (sh_basis.glsl).
  const std::uint32_t per_blocker = 2u * (1u + (n + 3u) / 4u + n);
  return std::max<std::uint32_t>(1u, budget / per_blocker);
}

vk::SubmitResult run_accumulate_log(vk::Context& dev, const vk::ComputePipeline& p, const AccumulateBuffers& b, std::size_t count,
                                    const ZhTable& log, std::uint32_t longest, const std::string& submit_name, float cut,
                                    std::uint32_t* chunks) {
  struct Push {
    std::uint32_t count, first, end, rows;
    float scale, cut;
    std::uint32_t chunk_first, chunk_count, chunk_add;
  };
  const std::uint32_t chunk = accumulate_log_chunk(dev.device_info(), log.order);
  const std::uint32_t n_chunks = longest <= chunk ? 1u : (longest + chunk - 1u) / chunk;
  if (chunks) *chunks = n_chunks;
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kAccBindReceivers, b.receivers, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kAccBindReceiverList, b.rlist, VK_FORMAT_R32_UINT),
      vk::Bind::texels_at(gpu::kAccBindListRange, b.ranges, VK_FORMAT_R32G32_UINT),
      vk::Bind::texels_at(gpu::kAccBindBlockers, b.blockers, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kAccBindWeights, b.weights, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kAccBindTable, b.table, VK_FORMAT_R32G32_SFLOAT),
      vk::Bind::buffer_at(gpu::kAccBindBasis, b.basis),
      vk::Bind::texels_at(gpu::kAccBindOut, b.out, VK_FORMAT_R32_SFLOAT)};
  return dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("accumulate_log");
    for (std::uint32_t k = 0; k < n_chunks; ++k) {
      const std::uint32_t first_blocker = k * chunk;
      const std::uint32_t in_chunk = n_chunks == 1 ? std::numeric_limits<std::uint32_t>::max() : chunk;
      dispatch_chunks<Push>(rec, p, binds, count, gpu::kAccumulateGroup, [&](std::uint32_t first, std::uint32_t end) {
        return Push{static_cast<std::uint32_t>(count), first, end, static_cast<std::uint32_t>(log.rows), log.scale, cut,
                    first_blocker, in_chunk, k > 0 ? 1u : 0u};
      });
      // The next chunk reads these sums back.
      if (k + 1 < n_chunks) rec.barrier();
    }
    rec.end_timer();
    rec.barrier();
  }, submit_name);
}

vk::SubmitResult run_exponentiate(vk::Context& dev, const vk::ComputePipeline& p, const ExponentiateBuffers& b, std::size_t count,
                                  std::uint32_t ol_count, int degree, const std::string& submit_name) {
  struct Push {
    std::uint32_t first, end, ol_count, degree, budget;
  };
  const std::uint32_t budget = loop_budget(dev.device_info());
  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kExpBindIn, b.in, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kExpBindOut, b.out),
      vk::Bind::texels_at(gpu::kExpBindOl, b.ol, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kExpBindSeries, b.series, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kExpBindStatus, b.status)};
  return dev.submit([&](vk::Recorder& rec) {
    rec.begin_timer("exponentiate");
    dispatch_chunks<Push>(rec, p, binds, count, gpu::kExponentiateGroup, [&](std::uint32_t first, std::uint32_t end) {
      return Push{first, end, ol_count, static_cast<std::uint32_t>(degree), budget};
    });
    rec.end_timer();
    rec.barrier();
  }, submit_name);
}

void reset_exp_status(vk::Context& dev, vk::Buffer& status, const std::string& name) {
  const std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  const std::uint32_t status0[gpu::kExpStatusWords] = {0, none, none, none, none};
  dev.ensure_buffer(status, sizeof status0, kStorage, vk::MemoryKind::Host, name);
  dev.upload(status, status0, sizeof status0);
}

namespace {
struct DeviceConstants {
  std::mutex m;
  vk::Buffer basis;
};
DeviceConstants& device_constants(vk::Context& dev) {
  return *dev.cached<DeviceConstants>("common.constants", [] { return std::make_shared<DeviceConstants>(); });
}
}  // namespace

namespace {

// download_field_column's pipeline and output buffer, per device.
struct ColumnState {
  std::mutex m;
  PipelineCache pipelines;
  vk::Buffer out;
};

}  // namespace

std::vector<float> download_field_column(vk::Context& dev, const DeviceField& field, std::size_t stride, std::size_t column,
                                         const std::string& what) {
  if (!field.buffer || stride == 0 || column >= stride || field.floats % stride != 0)
    throw std::logic_error(what + " on vulkan: column " + std::to_string(column) + " of rows of " + std::to_string(stride) + " floats in " +
                           std::to_string(field.floats) + " floats");
  const std::size_t rows = field.floats / stride;
  std::vector<float> v(rows);
  if (rows == 0) return v;
  if (rows > std::numeric_limits<std::uint32_t>::max() / 2 || field.floats > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument(what + " on vulkan: " + std::to_string(rows) + " rows exceed the 32-bit indexing");
  auto st = dev.cached<ColumnState>("common.field_column", [] { return std::make_shared<ColumnState>(); });
  std::lock_guard<std::mutex> lock(st->m);
  dev.ensure_buffer(st->out, rows * sizeof(float), kStorage, vk::MemoryKind::Device, "field column");
  vk::ComputePipeline& p = pipeline(dev, st->pipelines, "common.field_column", words(spv::common_field_column_comp), {});
  struct Push {
    std::uint32_t first, end, stride, column;
  };
  const std::vector<vk::Bind> binds = {vk::Bind::buffer_at(0, *field.buffer), vk::Bind::buffer_at(1, st->out)};
  dev.submit([&](vk::Recorder& rec) {
    dispatch_chunks<Push>(rec, p, binds, rows, gpu::kShadeGroup, [&](std::uint32_t first, std::uint32_t end) {
      return Push{first, end, static_cast<std::uint32_t>(stride), static_cast<std::uint32_t>(column)};
    });
    rec.barrier();
  }, what + " column");
  dev.download(st->out, v.data(), rows * sizeof(float));
  return v;
}

const vk::Buffer& basis_constants(vk::Context& dev) {
  DeviceConstants& c = device_constants(dev);
  std::lock_guard<std::mutex> lock(c.m);
  // A uniform buffer (sh_basis.glsl reads it as a uniform block); kBasisFloats is a multiple of 4.
  if (!c.basis)
    c.basis = dev.upload_vector(basis_recurrence_constants(), kStorage | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, "basis recurrence constants");
  return c.basis;
}

std::size_t AccumulationInputs::upload(vk::Context& dev, const ReceiverSoA& soa, const std::vector<std::uint32_t>& rl,
                                       const PackedBlockers& packed, const std::string& technique) {
  longest = 0;
  for (std::size_t i = 1; i < packed.ranges.size(); i += 2) longest = std::max(longest, packed.ranges[i]);
  const std::size_t before = dev.transfer_bytes().upload;
  upload_receivers(dev, receivers, soa, technique + " receivers", &receivers_hash);
  put_if_changed(dev, rlist, rlist_hash, rl, technique + " receiver lists");
  put_if_changed(dev, ranges, ranges_hash, packed.ranges, technique + " list ranges");
  put_if_changed(dev, blockers, blockers_hash, packed.sph, technique + " blocker spheres");
  put_if_changed(dev, weights, weights_hash, packed.w, technique + " band weights");
  return dev.transfer_bytes().upload - before;
}

bool exp_status_failed(const std::uint32_t (&status)[gpu::kExpStatusWords]) {
  const std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  return status[gpu::kExpStatusBadInput] != none || status[gpu::kExpStatusDcOverflow] != none ||
         status[gpu::kExpStatusOverflow] != none || status[gpu::kExpStatusLoopBudget] != none;
}

void throw_exp_errors(const std::uint32_t (&status)[gpu::kExpStatusWords], const float* log, int n2, const std::string& pass,
                      const std::function<std::string(std::size_t)>& receiver_name) {
  const std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  if (status[gpu::kExpStatusBadInput] != none) {
    const std::size_t i = status[gpu::kExpStatusBadInput] - 1;
    int k = 0;
    while (k < n2 - 1 && std::isfinite(log[i * n2 + k])) ++k;
    throw std::invalid_argument(pass + ": " + receiver_name(i) + " has log coefficient " + std::to_string(k) + " = " +
                                std::to_string(log[i * n2 + k]));
  }
  if (status[gpu::kExpStatusDcOverflow] != none) {
    const std::size_t i = status[gpu::kExpStatusDcOverflow] - 1;
    throw std::overflow_error(pass + ": receiver " + std::to_string(i) + ": DC coefficient " + std::to_string(log[i * n2]) +
                              " gives a mean log value whose exponential overflows");
  }
  if (status[gpu::kExpStatusOverflow] != none)
    throw std::overflow_error(pass + ": receiver " + std::to_string(status[gpu::kExpStatusOverflow] - 1) + ": a result coefficient overflowed");
  if (status[gpu::kExpStatusLoopBudget] != none)
    throw std::invalid_argument(pass + ": receiver " + std::to_string(status[gpu::kExpStatusLoopBudget] - 1) +
                                ": its exponential needs more loop iterations than this Vulkan driver runs per invocation "
                                "(llvmpipe's limit); lower 'order' or 'ps_degree', or use the cpu backend");
}

std::size_t first_bad_in_blocks(std::size_t n, std::size_t block, const std::function<std::size_t(std::size_t, std::size_t)>& first_in) {
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n, std::max<std::size_t>(block, 1)), n,
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t first) {
        // A later block cannot hold a smaller index than one already found.
        if (r.begin() >= first) return first;
        const std::size_t bad = first_in(r.begin(), r.end());
        return bad < r.end() ? std::min(first, bad) : first;
      },
      [](std::size_t x, std::size_t y) { return std::min(x, y); });
}

const vk::DeviceGBuffer* resident_display_planes(render::FrameContext& ctx, const float* depth, const glm::vec3* normal, int width,
                                                 int height) {
  const vk::DeviceGBuffer* d = ctx.device_copy<vk::DeviceGBuffer>(render::kGBuffer);
  if (!d || !d->normal_depth || !d->position_depth || !depth || !normal) return nullptr;
  return d->host_depth == depth && d->host_normal == normal && d->width == width && d->height == height ? d : nullptr;
}

}  // namespace softgi::techniques::common::gpu_passes
