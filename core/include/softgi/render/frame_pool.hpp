// Recycled storage for a backend's per-frame buffers. A frame's display-resolution planes (the
// G-buffer, per-pixel images, the composed result) are megabytes each; allocated afresh every frame,
// glibc maps them from the kernel and unmaps them when freed, so every frame pays a page fault per
// 4 KiB touched, which costs more than the passes' own memory traffic (bench/README.md, "Frame
// memory"). A Backend keeps one FramePool: the buffers a frame leaves behind (and those of a
// FrameResult handed back with Backend::recycle) are given to it, and the next frame's passes take
// them back instead of allocating.
#pragma once

#include <algorithm>
#include <any>
#include <cstddef>
#include <cstring>
#include <type_traits>
#include <mutex>
#include <typeindex>
#include <utility>
#include <vector>

#include "softgi/image.hpp"

namespace softgi::render {

struct GBuffer;

namespace detail {
// The byte Mode::Poison fills elements of T with: NaN bits (0xff) for floating-point values and
// vectors or arrays of them, 0x5a for integers and arrays of them (0xff would read as -1, a valid
// "none" in index planes).
template <class T, class = void>
struct PoisonByte {
  static constexpr int value = std::is_integral_v<T> ? 0x5a : 0xff;
};
template <class T>
struct PoisonByte<T, std::void_t<typename T::value_type>> {
  static constexpr int value = PoisonByte<typename T::value_type>::value;
};
}  // namespace detail

class FramePool {
 public:
  enum class Mode {
    On,
    Off,     // every take allocates and every give frees: the behaviour without a pool, for comparisons
    Poison,  // as On, and take_for_overwrite fills what it returns with a pattern (NaN bits in floating-
             // point elements, 0x5a bytes in integers), so that a pass that leaves an element unwritten
             // shows it in its output (tests)
  };
  // The mode from the environment variable SOFTGI_FRAME_POOL (on, off, poison; unset: on). Throws
  // std::invalid_argument naming the variable and its value for anything else.
  FramePool();
  FramePool(const FramePool&) = delete;
  FramePool& operator=(const FramePool&) = delete;

  // A vector of n elements. Its storage is a given buffer of the same element type whose capacity
  // is at least n (the smallest such, and not more than kMaxSlack times n, so that a small request
  // does not pin a large buffer), else a new one with capacity n + n / kHeadroom. The elements'
  // values are unspecified (a recycled buffer keeps its old values, a new or grown one is
  // value-initialised): for a caller that writes every element.
  template <class T>
  std::vector<T> take_for_overwrite(std::size_t n) {
    static_assert(std::is_trivially_copyable_v<T>, "the pool holds buffers of plain values");
    std::any a = take_slot(typeid(std::vector<T>), n, n * sizeof(T));
    std::vector<T> v;
    if (a.has_value())
      v = std::move(*std::any_cast<std::vector<T>>(&a));
    else if (mode() != Mode::Off)
      v.reserve(n + n / kHeadroom);  // untouched until used: no resident memory
    v.resize(n);
    if (mode() == Mode::Poison && n > 0) std::memset(static_cast<void*>(v.data()), detail::PoisonByte<T>::value, n * sizeof(T));
    return v;
  }
  // A vector of n copies of `fill`.
  template <class T>
  std::vector<T> take(std::size_t n, const T& fill) {
    std::vector<T> v = take_for_overwrite<T>(n);
    std::fill(v.begin(), v.end(), fill);
    return v;
  }
  // A w x h image whose pixels are unspecified (for a pass that writes every pixel), or `fill`.
  Image image_for_overwrite(int w, int h);
  Image image(int w, int h, glm::vec3 fill = glm::vec3(0.0f));

  // Hands a buffer to the pool for a later take. An empty one (no capacity) is dropped.
  template <class T>
  void give(std::vector<T>&& v) {
    if (v.capacity() == 0 || mode() == Mode::Off) {
      std::vector<T>().swap(v);
      return;
    }
    const std::size_t bytes = v.capacity() * sizeof(T);
    const std::size_t cap = v.capacity();
    add(typeid(std::vector<T>), std::any(std::move(v)), bytes, cap);
  }
  void give(Image&& img);
  void give(GBuffer&& gb);
  // A frame resource of a type the pool knows (Image, GBuffer, std::vector of glm::vec2/3/4, float,
  // double, std::int32_t, std::uint32_t, std::uint8_t, and std::vector of such vectors); anything
  // else is left as it is. True when it was taken.
  bool give_any(std::any& resource);

  // Ends a frame: buffers given more than kKeepFrames frames ago and not taken since are freed, so
  // the pool holds at most the last few frames' leftovers (a different resolution or technique
  // leaves nothing behind for long).
  void end_frame();
  // Frees everything held (before a memory check that the held buffers would fail).
  void clear();
  Mode mode() const { return mode_; }
  void set_mode(Mode m);  // Off frees what is held

  struct Stats {
    std::size_t held_bytes = 0;     // capacity held now
    std::size_t reused = 0;         // takes served from the pool, since creation
    std::size_t allocated = 0;      // takes that allocated
    std::size_t reused_bytes = 0;   // bytes of the takes served from the pool
    std::size_t allocated_bytes = 0;
  };
  Stats stats() const;

  static constexpr std::size_t kMaxSlack = 4;
  // A new buffer gets 1/kHeadroom more capacity than asked for, so that next frame's request for a
  // few more elements (receivers, surface pixels of an animated scene) still fits it instead of
  // allocating fresh pages.
  static constexpr std::size_t kHeadroom = 16;
  static constexpr unsigned kKeepFrames = 2;

 private:
  struct Slot {
    std::type_index type;
    std::any value;
    std::size_t bytes, capacity;
    unsigned long long frame;
  };
  // The buffer of `type` (std::vector<T>) with the smallest capacity >= n elements (and at most
  // kMaxSlack n), moved out of the pool; empty when there is none.
  std::any take_slot(std::type_index type, std::size_t n, std::size_t bytes);
  void add(std::type_index type, std::any value, std::size_t bytes, std::size_t capacity);

  Mode mode_ = Mode::On;
  mutable std::mutex mutex_;
  std::vector<Slot> slots_;
  unsigned long long frame_ = 0;
  Stats stats_;
};

}  // namespace softgi::render
