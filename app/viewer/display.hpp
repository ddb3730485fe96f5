// The viewer's window: GLFW, a Vulkan swapchain of its own and Dear ImGui drawn over the rendered
// image. Every backend's frame reaches the screen the same way: its final image (host memory, 8-bit
// display values) is copied into the swapchain image, then the interface is drawn over it, so the
// CPU and Vulkan backends show through one path.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

struct GLFWwindow;

namespace softgi::viewer {

struct DisplayOptions {
  int width = 1280, height = 800;  // window size in screen coordinates
  std::string title = "softgi-viewer";
  // The Khronos validation layer on the display's instance; its messages are printed on stderr
  // and counted (Display::validation_messages).
  bool validation = false;
};

// Where the image lies in the window (framebuffer pixels), for overlays and mouse picking.
struct ImageRect {
  float x = 0, y = 0, w = 0, h = 0;
};

// An 8-bit RGBA image, display-referred (sRGB encoded), row 0 at the top.
struct DisplayImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
};

class Display {
 public:
  // Opens the window and the Vulkan device that presents to it. Throws std::runtime_error naming
  // what is missing (no display, no Vulkan device that can present, no swapchain format it can copy
  // into).
  explicit Display(const DisplayOptions& options);
  ~Display();
  Display(const Display&) = delete;
  Display& operator=(const Display&) = delete;

  GLFWwindow* window() const;
  bool should_close() const;
  // Waits up to `seconds` for a window event (input, resize, expose).
  void wait_events(double seconds);
  // Polls window events and starts an ImGui frame.
  void begin_frame();
  // The image shown under the interface, scaled to fit the window with its aspect ratio kept.
  void set_image(DisplayImage image);
  // Framebuffer pixels kept free on the left and right (for the interface panels): the image is
  // fitted into the rest, unless that would leave it narrower than a quarter of the window.
  void set_margins(float left, float right);
  // Where set_image's image lies in the framebuffer (zero when there is none).
  ImageRect image_rect() const;
  // Finishes the ImGui frame and presents. A minimised (zero-size or iconified) window presents
  // nothing and returns false; an out-of-date swapchain is recreated. A lost device throws.
  bool end_frame();

  // The next presented frame (image and interface) is also read back and returned by
  // take_window_shot() (RGBA8, row 0 at the top); for documentation and tests of the window itself.
  void request_window_shot();
  // The frame read back since request_window_shot(), once it has been presented (empty before).
  DisplayImage take_window_shot();

  // Window control for scripted sessions: the window's size in screen coordinates, minimise and
  // restore.
  void resize(int width, int height);
  void iconify();
  void restore();
  // Framebuffer size in pixels (0 x 0 when minimised).
  void framebuffer_size(int& width, int& height) const;
  // The swapchain's recreations so far (resize, out of date).
  int swapchain_recreations() const;

  std::string device_name() const;
  // Validation-layer warnings and errors reported on the display's device so far.
  int validation_messages() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softgi::viewer
