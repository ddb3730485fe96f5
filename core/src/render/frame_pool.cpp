#include "softgi/render/frame_pool.hpp"

#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "softgi/render/gbuffer.hpp"

namespace softgi::render {

FramePool::FramePool() {
  const char* env = std::getenv("SOFTGI_FRAME_POOL");
  const std::string v = env ? env : "";
  if (v.empty() || v == "on")
    mode_ = Mode::On;
  else if (v == "off")
    mode_ = Mode::Off;
  else if (v == "poison")
    mode_ = Mode::Poison;
  else
    throw std::invalid_argument("SOFTGI_FRAME_POOL is '" + v + "'; expected on, off or poison");
}

void FramePool::set_mode(Mode m) {
  mode_ = m;
  if (m == Mode::Off) clear();
}

Image FramePool::image_for_overwrite(int w, int h) {
  Image img;
  img.width = w;
  img.height = h;
  img.rgb = take_for_overwrite<glm::vec3>(static_cast<std::size_t>(std::max(w, 0)) * static_cast<std::size_t>(std::max(h, 0)));
  return img;
}

Image FramePool::image(int w, int h, glm::vec3 fill) {
  Image img = image_for_overwrite(w, h);
  std::fill(img.rgb.begin(), img.rgb.end(), fill);
  return img;
}

void FramePool::give(Image&& img) {
  give(std::move(img.rgb));
  img = Image();
}

GBuffer GBuffer::for_overwrite(int w, int h, int scale, FramePool& pool, unsigned planes) {
  GBuffer gb;
  gb.width = w;
  gb.height = h;
  gb.scale = scale;
  gb.planes = planes & kGBufferAll;
  const std::size_t n = static_cast<std::size_t>(std::max(w, 0)) * static_cast<std::size_t>(std::max(h, 0));
  if (planes & kGBufferSurface) {
    gb.position = pool.take_for_overwrite<glm::vec3>(n);
    gb.normal = pool.take_for_overwrite<glm::vec3>(n);
    gb.depth = pool.take_for_overwrite<float>(n);
  }
  if (planes & kGBufferAlbedo) gb.albedo = pool.take_for_overwrite<glm::vec3>(n);
  gb.object = pool.take_for_overwrite<std::int32_t>(n);
  gb.primitive = pool.take_for_overwrite<std::int32_t>(n);
  gb.barycentric = pool.take_for_overwrite<glm::vec2>(n);
  if (planes & kGBufferViewDir) gb.view_dir = pool.take_for_overwrite<glm::vec3>(n);
  return gb;
}

void FramePool::give(GBuffer&& gb) {
  give(std::move(gb.position));
  give(std::move(gb.normal));
  give(std::move(gb.depth));
  give(std::move(gb.albedo));
  give(std::move(gb.object));
  give(std::move(gb.primitive));
  give(std::move(gb.barycentric));
  give(std::move(gb.view_dir));
  gb = GBuffer();
}

namespace {

template <class T>
bool give_vector(FramePool& pool, std::any& a) {
  if (auto* v = std::any_cast<std::vector<T>>(&a)) {
    pool.give(std::move(*v));
    return true;
  }
  if (auto* vv = std::any_cast<std::vector<std::vector<T>>>(&a)) {
    for (auto& v : *vv) pool.give(std::move(v));
    return true;
  }
  return false;
}

}  // namespace

bool FramePool::give_any(std::any& a) {
  if (auto* img = std::any_cast<Image>(&a)) {
    give(std::move(*img));
    return true;
  }
  if (auto* gb = std::any_cast<GBuffer>(&a)) {
    give(std::move(*gb));
    return true;
  }
  return give_vector<glm::vec3>(*this, a) || give_vector<glm::vec2>(*this, a) || give_vector<glm::vec4>(*this, a) ||
         give_vector<float>(*this, a) || give_vector<double>(*this, a) || give_vector<std::int32_t>(*this, a) ||
         give_vector<std::uint32_t>(*this, a) || give_vector<std::uint8_t>(*this, a);
}

std::any FramePool::take_slot(std::type_index type, std::size_t n, std::size_t bytes) {
  if (n == 0 || mode_ == Mode::Off) {
    if (n > 0) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.allocated;
      stats_.allocated_bytes += bytes;
    }
    return {};
  }
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t best = slots_.size();
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    const Slot& s = slots_[i];
    if (s.type != type || s.capacity < n || s.capacity / kMaxSlack > n) continue;
    if (best == slots_.size() || s.capacity < slots_[best].capacity) best = i;
  }
  if (best == slots_.size()) {
    ++stats_.allocated;
    stats_.allocated_bytes += bytes;
    return {};
  }
  std::any v = std::move(slots_[best].value);
  stats_.held_bytes -= slots_[best].bytes;
  slots_.erase(slots_.begin() + static_cast<std::ptrdiff_t>(best));
  ++stats_.reused;
  stats_.reused_bytes += bytes;
  return v;
}

void FramePool::add(std::type_index type, std::any value, std::size_t bytes, std::size_t capacity) {
  std::lock_guard<std::mutex> lock(mutex_);
  slots_.push_back(Slot{type, std::move(value), bytes, capacity, frame_});
  stats_.held_bytes += bytes;
}

void FramePool::end_frame() {
  std::vector<Slot> dropped;  // freed outside the lock
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++frame_;
    for (std::size_t i = 0; i < slots_.size();) {
      if (frame_ - slots_[i].frame > kKeepFrames) {
        stats_.held_bytes -= slots_[i].bytes;
        dropped.push_back(std::move(slots_[i]));
        slots_.erase(slots_.begin() + static_cast<std::ptrdiff_t>(i));
      } else {
        ++i;
      }
    }
  }
}

void FramePool::clear() {
  std::vector<Slot> dropped;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    dropped.swap(slots_);
    stats_.held_bytes = 0;
  }
}

FramePool::Stats FramePool::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace softgi::render
