#include "display.hpp"

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_vulkan.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "softgi/backends/vulkan/context.hpp"
#include "softgi/backends/vulkan/loader_pin.hpp"

namespace softgi::viewer {

namespace {

namespace vulkan = backends::vulkan;

void check(VkResult r, const char* what) {
  if (r == VK_SUCCESS) return;
  if (r == VK_ERROR_DEVICE_LOST)
    throw std::runtime_error(std::string("display: the Vulkan device was lost (") + what + ")");
  throw std::runtime_error(std::string("display: ") + what + " failed: " + vulkan::to_string(r));
}

// ImGui's Vulkan backend reports its own call results here; it has no way to propagate them.
void imgui_check(VkResult r) {
  if (r != VK_SUCCESS) std::fprintf(stderr, "softgi-viewer: error: ImGui Vulkan call failed: %s\n", vulkan::to_string(r));
}

std::atomic<int> g_validation_messages{0};

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data, void*) {
  if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    ++g_validation_messages;
    std::fprintf(stderr, "softgi-viewer: vulkan validation %s: %s\n",
                 severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning",
                 data && data->pMessage ? data->pMessage : "(no message)");
  }
  return VK_FALSE;
}

void on_glfw_error(int code, const char* text) { std::fprintf(stderr, "softgi-viewer: GLFW error %d: %s\n", code, text); }

constexpr int kFramesInFlight = 2;

}  // namespace

struct Display::Impl {
  GLFWwindow* window = nullptr;
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkSurfaceKHR surface = VK_NULL_HANDLE;
  VkPhysicalDevice gpu = VK_NULL_HANDLE;
  std::string gpu_name;
  std::uint32_t queue_family = 0;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  VkSurfaceFormatKHR format{};
  bool swap_red_blue = false;  // the swapchain stores B, G, R, A
  VkRenderPass render_pass = VK_NULL_HANDLE;
  VkDescriptorPool descriptor_pool = VK_NULL_HANDLE;
  VkCommandPool command_pool = VK_NULL_HANDLE;

  VkSwapchainKHR swapchain = VK_NULL_HANDLE;
  VkExtent2D extent{0, 0};
  std::uint32_t min_image_count = 2;
  std::vector<VkImage> images;
  std::vector<VkImageView> views;
  std::vector<VkFramebuffer> framebuffers;
  std::vector<VkSemaphore> render_done;  // one per swapchain image
  bool rebuild = false, can_read_back = false;
  int recreations = 0;

  struct Frame {
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
    VkSemaphore acquired = VK_NULL_HANDLE;
    VkBuffer staging = VK_NULL_HANDLE;
    VkDeviceMemory staging_memory = VK_NULL_HANDLE;
    VkDeviceSize staging_size = 0;
    void* mapped = nullptr;
    std::uint64_t filled_version = ~0ull;  // which image/extent the staging buffer holds
  };
  std::array<Frame, kFramesInFlight> frames;
  int frame_index = 0;

  DisplayImage image;
  std::uint64_t image_version = 0;
  float left_margin = 0.0f, right_margin = 0.0f;
  bool shot_requested = false;
  DisplayImage shot;
  VkBuffer shot_buffer = VK_NULL_HANDLE;
  VkDeviceMemory shot_memory = VK_NULL_HANDLE;
  void* shot_mapped = nullptr;
  bool imgui_ready = false, imgui_vulkan_ready = false;

  ~Impl();
  void create_instance(bool validation);
  void pick_device();
  void create_device();
  void create_render_pass();
  void create_swapchain();
  void destroy_swapchain();
  void create_frames();
  void host_buffer(VkDeviceSize bytes, VkBufferUsageFlags usage, VkBuffer& buffer, VkDeviceMemory& memory, void*& mapped);
  void ensure_staging(Frame& f, VkDeviceSize bytes);
  void fill_staging(Frame& f);
  std::uint32_t memory_type(std::uint32_t bits, VkMemoryPropertyFlags want) const;
  void init_imgui();
  ImageRect rect() const;
};

void Display::Impl::create_instance(bool validation) {
  std::uint32_t n = 0;
  const char** glfw_ext = glfwGetRequiredInstanceExtensions(&n);
  if (!glfw_ext) throw std::runtime_error("display: GLFW found no Vulkan surface extensions for this window system");
  std::vector<const char*> ext(glfw_ext, glfw_ext + n);
  std::vector<const char*> layers;
  if (validation) {
    std::uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> props(count);
    vkEnumerateInstanceLayerProperties(&count, props.data());
    const bool have = std::any_of(props.begin(), props.end(),
                                  [](const VkLayerProperties& p) { return std::strcmp(p.layerName, "VK_LAYER_KHRONOS_validation") == 0; });
    if (!have)
      throw std::runtime_error(
          "display: validation requested but VK_LAYER_KHRONOS_validation is not installed (Debian: vulkan-validationlayers)");
    layers.push_back("VK_LAYER_KHRONOS_validation");
    ext.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "softgi-viewer";
  app.apiVersion = VK_API_VERSION_1_1;
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  ci.enabledExtensionCount = static_cast<std::uint32_t>(ext.size());
  ci.ppEnabledExtensionNames = ext.data();
  ci.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  VkDebugUtilsMessengerCreateInfoEXT mi{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  mi.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  mi.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                   VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  mi.pfnUserCallback = on_validation;
  if (validation) ci.pNext = &mi;  // instance creation and destruction are checked too
  check(vkCreateInstance(&ci, nullptr, &instance), "vkCreateInstance");
  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    if (!create) throw std::runtime_error("display: vkCreateDebugUtilsMessengerEXT is missing");
    check(create(instance, &mi, nullptr, &messenger), "vkCreateDebugUtilsMessengerEXT");
  }
}

void Display::Impl::pick_device() {
  std::uint32_t n = 0;
  vkEnumeratePhysicalDevices(instance, &n, nullptr);
  std::vector<VkPhysicalDevice> gpus(n);
  vkEnumeratePhysicalDevices(instance, &n, gpus.data());
  // A GPU that can present to the window, else any device that can (lavapipe).
  int best = -1, best_rank = -1;
  std::uint32_t best_family = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint32_t qn = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(gpus[i], &qn, nullptr);
    std::vector<VkQueueFamilyProperties> qf(qn);
    vkGetPhysicalDeviceQueueFamilyProperties(gpus[i], &qn, qf.data());
    for (std::uint32_t q = 0; q < qn; ++q) {
      VkBool32 present = VK_FALSE;
      vkGetPhysicalDeviceSurfaceSupportKHR(gpus[i], q, surface, &present);
      if (!(qf[q].queueFlags & VK_QUEUE_GRAPHICS_BIT) || !present) continue;
      VkPhysicalDeviceProperties p;
      vkGetPhysicalDeviceProperties(gpus[i], &p);
      const int rank = p.deviceType == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU     ? 3
                       : p.deviceType == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU ? 2
                       : p.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU            ? 0
                                                                                : 1;
      if (rank > best_rank) best = static_cast<int>(i), best_rank = rank, best_family = q;
      break;
    }
  }
  if (best < 0) throw std::runtime_error("display: no Vulkan device can present to this window (" + std::to_string(n) + " devices)");
  gpu = gpus[best];
  queue_family = best_family;
  VkPhysicalDeviceProperties p;
  vkGetPhysicalDeviceProperties(gpu, &p);
  gpu_name = p.deviceName;
}

void Display::Impl::create_device() {
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qi{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qi.queueFamilyIndex = queue_family;
  qi.queueCount = 1;
  qi.pQueuePriorities = &priority;
  const char* ext[] = {VK_KHR_SWAPCHAIN_EXTENSION_NAME};
  VkDeviceCreateInfo ci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  ci.queueCreateInfoCount = 1;
  ci.pQueueCreateInfos = &qi;
  ci.enabledExtensionCount = 1;
  ci.ppEnabledExtensionNames = ext;
  check(vkCreateDevice(gpu, &ci, nullptr, &device), "vkCreateDevice");
  vkGetDeviceQueue(device, queue_family, 0, &queue);

  // The rendered image is written in 8-bit display values, so the swapchain must store them as
  // given: a UNORM format (an sRGB one would encode them a second time).
  std::uint32_t n = 0;
  vkGetPhysicalDeviceSurfaceFormatsKHR(gpu, surface, &n, nullptr);
  std::vector<VkSurfaceFormatKHR> formats(n);
  vkGetPhysicalDeviceSurfaceFormatsKHR(gpu, surface, &n, formats.data());
  bool found = false;
  for (VkFormat want : {VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_R8G8B8A8_UNORM})
    for (const auto& f : formats)
      if (!found && f.format == want && f.colorSpace == VK_COLOR_SPACE_SRGB_NONLINEAR_KHR) format = f, found = true;
  if (!found) throw std::runtime_error("display: the surface offers no B8G8R8A8_UNORM or R8G8B8A8_UNORM format");
  swap_red_blue = format.format == VK_FORMAT_B8G8R8A8_UNORM;

  VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pi.queueFamilyIndex = queue_family;
  check(vkCreateCommandPool(device, &pi, nullptr, &command_pool), "vkCreateCommandPool");

  VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 16}};
  VkDescriptorPoolCreateInfo di{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  di.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
  di.maxSets = 16;
  di.poolSizeCount = 1;
  di.pPoolSizes = sizes;
  check(vkCreateDescriptorPool(device, &di, nullptr, &descriptor_pool), "vkCreateDescriptorPool");
}

void Display::Impl::create_render_pass() {
  // The image is copied into the swapchain image first (transfer destination); the interface is
  // then drawn over it (load, not clear).
  VkAttachmentDescription a{};
  a.format = format.format;
  a.samples = VK_SAMPLE_COUNT_1_BIT;
  a.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
  a.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  a.stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  a.stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  a.initialLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  a.finalLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
  VkAttachmentReference ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub{};
  sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  sub.colorAttachmentCount = 1;
  sub.pColorAttachments = &ref;
  VkSubpassDependency dep{};
  dep.srcSubpass = VK_SUBPASS_EXTERNAL;
  dep.dstSubpass = 0;
  dep.srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  dep.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  dep.dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  dep.dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  VkRenderPassCreateInfo ci{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  ci.attachmentCount = 1;
  ci.pAttachments = &a;
  ci.subpassCount = 1;
  ci.pSubpasses = &sub;
  ci.dependencyCount = 1;
  ci.pDependencies = &dep;
  check(vkCreateRenderPass(device, &ci, nullptr, &render_pass), "vkCreateRenderPass");
}

void Display::Impl::create_swapchain() {
  VkSurfaceCapabilitiesKHR caps;
  check(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(gpu, surface, &caps), "vkGetPhysicalDeviceSurfaceCapabilitiesKHR");
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(window, &fw, &fh);
  VkExtent2D e = caps.currentExtent;
  if (e.width == 0xFFFFFFFFu) e = {static_cast<std::uint32_t>(fw), static_cast<std::uint32_t>(fh)};
  e.width = std::clamp(e.width, caps.minImageExtent.width, caps.maxImageExtent.width);
  e.height = std::clamp(e.height, caps.minImageExtent.height, caps.maxImageExtent.height);
  extent = e;
  if (e.width == 0 || e.height == 0) return;  // minimised: no swapchain until the window has a size
  if (!(caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT))
    throw std::runtime_error("display: the surface's images cannot be copied into (no TRANSFER_DST usage)");
  min_image_count = std::max(2u, caps.minImageCount);
  std::uint32_t count = min_image_count + 1;
  if (caps.maxImageCount) count = std::min(count, caps.maxImageCount);
  VkSwapchainKHR old = swapchain;
  VkSwapchainCreateInfoKHR ci{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  ci.surface = surface;
  ci.minImageCount = count;
  ci.imageFormat = format.format;
  ci.imageColorSpace = format.colorSpace;
  ci.imageExtent = e;
  ci.imageArrayLayers = 1;
  ci.imageUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT |
                  (caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT);  // window shots read it back
  can_read_back = (caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT) != 0;
  ci.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ci.preTransform = (caps.supportedTransforms & VK_SURFACE_TRANSFORM_IDENTITY_BIT_KHR) ? VK_SURFACE_TRANSFORM_IDENTITY_BIT_KHR
                                                                                         : caps.currentTransform;
  ci.compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR)
                          ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                          : static_cast<VkCompositeAlphaFlagBitsKHR>(caps.supportedCompositeAlpha & -caps.supportedCompositeAlpha);
  ci.presentMode = VK_PRESENT_MODE_FIFO_KHR;  // always available
  ci.clipped = VK_TRUE;
  ci.oldSwapchain = old;
  check(vkCreateSwapchainKHR(device, &ci, nullptr, &swapchain), "vkCreateSwapchainKHR");
  if (old != VK_NULL_HANDLE) vkDestroySwapchainKHR(device, old, nullptr);

  std::uint32_t n = 0;
  vkGetSwapchainImagesKHR(device, swapchain, &n, nullptr);
  images.resize(n);
  vkGetSwapchainImagesKHR(device, swapchain, &n, images.data());
  for (VkImage img : images) {
    VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    vi.image = img;
    vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vi.format = format.format;
    vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    VkImageView v;
    check(vkCreateImageView(device, &vi, nullptr, &v), "vkCreateImageView");
    views.push_back(v);
    VkFramebufferCreateInfo fi{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fi.renderPass = render_pass;
    fi.attachmentCount = 1;
    fi.pAttachments = &v;
    fi.width = e.width;
    fi.height = e.height;
    fi.layers = 1;
    VkFramebuffer fb;
    check(vkCreateFramebuffer(device, &fi, nullptr, &fb), "vkCreateFramebuffer");
    framebuffers.push_back(fb);
    VkSemaphoreCreateInfo si{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore s;
    check(vkCreateSemaphore(device, &si, nullptr, &s), "vkCreateSemaphore");
    render_done.push_back(s);
  }
  if (imgui_vulkan_ready) ImGui_ImplVulkan_SetMinImageCount(min_image_count);
  for (auto& f : frames) f.filled_version = ~0ull;
}

void Display::Impl::destroy_swapchain() {
  for (auto fb : framebuffers) vkDestroyFramebuffer(device, fb, nullptr);
  for (auto v : views) vkDestroyImageView(device, v, nullptr);
  for (auto s : render_done) vkDestroySemaphore(device, s, nullptr);
  framebuffers.clear();
  views.clear();
  render_done.clear();
  images.clear();
}

void Display::Impl::create_frames() {
  for (auto& f : frames) {
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = command_pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    check(vkAllocateCommandBuffers(device, &ai, &f.cmd), "vkAllocateCommandBuffers");
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
    check(vkCreateFence(device, &fi, nullptr, &f.fence), "vkCreateFence");
    VkSemaphoreCreateInfo si{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    check(vkCreateSemaphore(device, &si, nullptr, &f.acquired), "vkCreateSemaphore");
  }
}

std::uint32_t Display::Impl::memory_type(std::uint32_t bits, VkMemoryPropertyFlags want) const {
  VkPhysicalDeviceMemoryProperties mp;
  vkGetPhysicalDeviceMemoryProperties(gpu, &mp);
  for (std::uint32_t i = 0; i < mp.memoryTypeCount; ++i)
    if ((bits & (1u << i)) && (mp.memoryTypes[i].propertyFlags & want) == want) return i;
  throw std::runtime_error("display: no host-visible coherent memory for the image upload");
}

void Display::Impl::host_buffer(VkDeviceSize bytes, VkBufferUsageFlags usage, VkBuffer& buffer, VkDeviceMemory& memory, void*& mapped) {
  if (buffer != VK_NULL_HANDLE) {
    vkDestroyBuffer(device, buffer, nullptr);
    vkFreeMemory(device, memory, nullptr);
    buffer = VK_NULL_HANDLE;
    memory = VK_NULL_HANDLE;
  }
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = bytes;
  bi.usage = usage;
  check(vkCreateBuffer(device, &bi, nullptr, &buffer), "vkCreateBuffer (host transfer)");
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device, buffer, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  check(vkAllocateMemory(device, &ai, nullptr, &memory), "vkAllocateMemory (host transfer)");
  check(vkBindBufferMemory(device, buffer, memory, 0), "vkBindBufferMemory");
  check(vkMapMemory(device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
}

void Display::Impl::ensure_staging(Frame& f, VkDeviceSize bytes) {
  if (f.staging_size >= bytes) return;
  host_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, f.staging, f.staging_memory, f.mapped);
  f.staging_size = bytes;
  f.filled_version = ~0ull;
}

ImageRect Display::Impl::rect() const {
  if (image.width <= 0 || image.height <= 0 || extent.width == 0 || extent.height == 0) return {};
  const float W = static_cast<float>(extent.width);
  const bool room = W - left_margin - right_margin >= 0.25f * W;
  const float margin = room ? left_margin : 0.0f, avail = room ? W - left_margin - right_margin : W;
  const float s = std::min(avail / static_cast<float>(image.width), static_cast<float>(extent.height) / static_cast<float>(image.height));
  ImageRect r;
  r.w = static_cast<float>(image.width) * s;
  r.h = static_cast<float>(image.height) * s;
  r.x = std::floor(margin + (avail - r.w) * 0.5f);
  r.y = std::floor((static_cast<float>(extent.height) - r.h) * 0.5f);
  return r;
}

void Display::Impl::fill_staging(Frame& f) {
  // The window's pixels: a dark background and the image scaled to fit (nearest texel: the
  // rendered pixels stay visible as they are, no filter of the viewer's own in what is judged).
  const std::uint64_t version = image_version * 65537ull + extent.width * 131ull + extent.height;
  if (f.filled_version == version) return;
  const std::uint32_t W = extent.width, H = extent.height;
  auto* out = static_cast<std::uint8_t*>(f.mapped);
  const ImageRect r = rect();
  const int x0 = static_cast<int>(r.x), y0 = static_cast<int>(r.y);
  const int rw = static_cast<int>(r.w), rh = static_cast<int>(r.h);
  const int ri = swap_red_blue ? 2 : 0, bi = swap_red_blue ? 0 : 2;
  for (std::uint32_t y = 0; y < H; ++y) {
    std::uint8_t* row = out + static_cast<std::size_t>(y) * W * 4;
    const int iy = static_cast<int>(y) - y0;
    const bool in_rows = iy >= 0 && iy < rh;
    const int sy = in_rows ? std::min(image.height - 1, static_cast<int>((static_cast<long long>(iy) * image.height) / std::max(1, rh))) : 0;
    for (std::uint32_t x = 0; x < W; ++x) {
      std::uint8_t* px = row + x * 4;
      const int ix = static_cast<int>(x) - x0;
      if (in_rows && ix >= 0 && ix < rw) {
        const int sx = std::min(image.width - 1, static_cast<int>((static_cast<long long>(ix) * image.width) / std::max(1, rw)));
        const std::uint8_t* src = image.rgba.data() + (static_cast<std::size_t>(sy) * image.width + sx) * 4;
        px[ri] = src[0];
        px[1] = src[1];
        px[bi] = src[2];
        px[3] = 255;
      } else {
        px[0] = px[1] = px[2] = 24;
        px[3] = 255;
      }
    }
  }
  f.filled_version = version;
}

void Display::Impl::init_imgui() {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // the viewer saves its settings itself (JSON)
  ImGui::StyleColorsDark();
  imgui_ready = true;
  ImGui_ImplGlfw_InitForVulkan(window, true);
  ImGui_ImplVulkan_InitInfo ii{};
  ii.Instance = instance;
  ii.PhysicalDevice = gpu;
  ii.Device = device;
  ii.QueueFamily = queue_family;
  ii.Queue = queue;
  ii.DescriptorPool = descriptor_pool;
  ii.MinImageCount = min_image_count;
  ii.ImageCount = std::max<std::uint32_t>(min_image_count, static_cast<std::uint32_t>(images.size()));
  ii.MSAASamples = VK_SAMPLE_COUNT_1_BIT;
  ii.CheckVkResultFn = imgui_check;
  if (!ImGui_ImplVulkan_Init(&ii, render_pass)) throw std::runtime_error("display: ImGui's Vulkan backend failed to start");
  imgui_vulkan_ready = true;

  // Font atlas upload: one submission, waited for.
  VkCommandBuffer cmd = frames[0].cmd;
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
  ImGui_ImplVulkan_CreateFontsTexture(cmd);
  check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  check(vkQueueSubmit(queue, 1, &si, VK_NULL_HANDLE), "vkQueueSubmit (fonts)");
  check(vkQueueWaitIdle(queue), "vkQueueWaitIdle (fonts)");
  ImGui_ImplVulkan_DestroyFontUploadObjects();
}

// Undoes whatever was built, in reverse order; every handle may still be null (a constructor that
// failed midway).
Display::Impl::~Impl() {
  if (device != VK_NULL_HANDLE) vkDeviceWaitIdle(device);
  if (imgui_vulkan_ready) ImGui_ImplVulkan_Shutdown();
  if (imgui_ready) {
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
  if (device != VK_NULL_HANDLE) {
    destroy_swapchain();
    if (swapchain != VK_NULL_HANDLE) vkDestroySwapchainKHR(device, swapchain, nullptr);
    for (auto& f : frames) {
      if (f.staging != VK_NULL_HANDLE) vkDestroyBuffer(device, f.staging, nullptr);
      if (f.staging_memory != VK_NULL_HANDLE) vkFreeMemory(device, f.staging_memory, nullptr);
      if (f.fence != VK_NULL_HANDLE) vkDestroyFence(device, f.fence, nullptr);
      if (f.acquired != VK_NULL_HANDLE) vkDestroySemaphore(device, f.acquired, nullptr);
    }
    if (shot_buffer != VK_NULL_HANDLE) vkDestroyBuffer(device, shot_buffer, nullptr);
    if (shot_memory != VK_NULL_HANDLE) vkFreeMemory(device, shot_memory, nullptr);
    if (command_pool != VK_NULL_HANDLE) vkDestroyCommandPool(device, command_pool, nullptr);
    if (descriptor_pool != VK_NULL_HANDLE) vkDestroyDescriptorPool(device, descriptor_pool, nullptr);
    if (render_pass != VK_NULL_HANDLE) vkDestroyRenderPass(device, render_pass, nullptr);
    vkDestroyDevice(device, nullptr);
  }
  if (surface != VK_NULL_HANDLE) vkDestroySurfaceKHR(instance, surface, nullptr);
  if (messenger != VK_NULL_HANDLE) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance, messenger, nullptr);
  }
  if (instance != VK_NULL_HANDLE) vkDestroyInstance(instance, nullptr);
  if (window) glfwDestroyWindow(window);
  glfwTerminate();
}

Display::Display(const DisplayOptions& options) : impl_(std::make_unique<Impl>()) {
  glfwSetErrorCallback(on_glfw_error);
  if (!glfwInit()) throw std::runtime_error("display: GLFW could not start (no display? set DISPLAY, or run under xvfb-run)");
  if (!glfwVulkanSupported()) throw std::runtime_error("display: GLFW finds no Vulkan loader or no surface support");
  // A constructor that throws destroys impl_, whose destructor undoes what was built so far.
  Impl& d = *impl_;
  {
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    d.window = glfwCreateWindow(options.width, options.height, options.title.c_str(), nullptr, nullptr);
    if (!d.window) throw std::runtime_error("display: could not open a " + std::to_string(options.width) + "x" + std::to_string(options.height) + " window");
    d.create_instance(options.validation);
    check(glfwCreateWindowSurface(d.instance, d.window, nullptr, &d.surface), "glfwCreateWindowSurface");
    d.pick_device();
    d.create_device();
    d.create_render_pass();
    d.create_frames();
    d.create_swapchain();
    d.init_imgui();
    backends::vulkan::pin_loaded_libraries();  // the ICD and the window-system libraries the loader opened
  }
}

Display::~Display() = default;

GLFWwindow* Display::window() const { return impl_->window; }
bool Display::should_close() const { return glfwWindowShouldClose(impl_->window); }

void Display::wait_events(double seconds) { glfwWaitEventsTimeout(seconds); }

void Display::begin_frame() {
  glfwPollEvents();
  ImGui_ImplVulkan_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
}

void Display::set_image(DisplayImage image) {
  impl_->image = std::move(image);
  ++impl_->image_version;
}

void Display::set_margins(float left, float right) {
  left = std::max(0.0f, left);
  right = std::max(0.0f, right);
  if (left != impl_->left_margin || right != impl_->right_margin) {
    impl_->left_margin = left;
    impl_->right_margin = right;
    for (auto& f : impl_->frames) f.filled_version = ~0ull;
  }
}

ImageRect Display::image_rect() const { return impl_->rect(); }

bool Display::end_frame() {
  Impl& d = *impl_;
  ImGui::Render();
  ImDrawData* draw = ImGui::GetDrawData();
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(d.window, &fw, &fh);
  const bool minimised = fw == 0 || fh == 0 || glfwGetWindowAttrib(d.window, GLFW_ICONIFIED);
  if (minimised) return false;
  if (d.rebuild || d.swapchain == VK_NULL_HANDLE || static_cast<std::uint32_t>(fw) != d.extent.width ||
      static_cast<std::uint32_t>(fh) != d.extent.height) {
    check(vkDeviceWaitIdle(d.device), "vkDeviceWaitIdle");
    d.destroy_swapchain();
    d.create_swapchain();
    d.rebuild = false;
    ++d.recreations;
    if (d.swapchain == VK_NULL_HANDLE || d.extent.width == 0) return false;
  }

  Impl::Frame& f = d.frames[d.frame_index];
  check(vkWaitForFences(d.device, 1, &f.fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  std::uint32_t index = 0;
  VkResult r = vkAcquireNextImageKHR(d.device, d.swapchain, UINT64_MAX, f.acquired, VK_NULL_HANDLE, &index);
  if (r == VK_ERROR_OUT_OF_DATE_KHR) {
    d.rebuild = true;
    return false;
  }
  if (r != VK_SUBOPTIMAL_KHR) check(r, "vkAcquireNextImageKHR");
  check(vkResetFences(d.device, 1, &f.fence), "vkResetFences");

  const VkDeviceSize bytes = static_cast<VkDeviceSize>(d.extent.width) * d.extent.height * 4;
  d.ensure_staging(f, bytes);
  d.fill_staging(f);

  VkCommandBuffer cmd = f.cmd;
  check(vkResetCommandBuffer(cmd, 0), "vkResetCommandBuffer");
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = 0;
  b.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  b.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  b.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = d.images[index];
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 1, &b);
  VkBufferImageCopy copy{};
  copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  copy.imageExtent = {d.extent.width, d.extent.height, 1};
  vkCmdCopyBufferToImage(cmd, f.staging, d.images[index], VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &copy);

  VkRenderPassBeginInfo rp{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
  rp.renderPass = d.render_pass;
  rp.framebuffer = d.framebuffers[index];
  rp.renderArea.extent = d.extent;
  vkCmdBeginRenderPass(cmd, &rp, VK_SUBPASS_CONTENTS_INLINE);
  ImGui_ImplVulkan_RenderDrawData(draw, cmd);
  vkCmdEndRenderPass(cmd);
  const bool shoot = d.shot_requested && d.can_read_back;
  if (shoot) {
    d.host_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, d.shot_buffer, d.shot_memory, d.shot_mapped);
    VkImageMemoryBarrier t{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    t.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    t.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    t.oldLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    t.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    t.srcQueueFamilyIndex = t.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    t.image = d.images[index];
    t.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 1, &t);
    vkCmdCopyImageToBuffer(cmd, d.images[index], VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, d.shot_buffer, 1, &copy);
    t.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    t.dstAccessMask = 0;
    t.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    t.newLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 0, nullptr, 1, &t);
  }
  check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");

  const VkPipelineStageFlags wait = VK_PIPELINE_STAGE_TRANSFER_BIT;
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.waitSemaphoreCount = 1;
  si.pWaitSemaphores = &f.acquired;
  si.pWaitDstStageMask = &wait;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  si.signalSemaphoreCount = 1;
  si.pSignalSemaphores = &d.render_done[index];
  check(vkQueueSubmit(d.queue, 1, &si, f.fence), "vkQueueSubmit");
  if (shoot) {
    check(vkWaitForFences(d.device, 1, &f.fence, VK_TRUE, UINT64_MAX), "vkWaitForFences (window shot)");
    d.shot.width = static_cast<int>(d.extent.width);
    d.shot.height = static_cast<int>(d.extent.height);
    d.shot.rgba.resize(static_cast<std::size_t>(bytes));
    const auto* src = static_cast<const std::uint8_t*>(d.shot_mapped);
    const int ri = d.swap_red_blue ? 2 : 0, bi2 = d.swap_red_blue ? 0 : 2;
    for (std::size_t i = 0; i < d.shot.rgba.size(); i += 4) {
      d.shot.rgba[i] = src[i + ri];
      d.shot.rgba[i + 1] = src[i + 1];
      d.shot.rgba[i + 2] = src[i + bi2];
      d.shot.rgba[i + 3] = 255;
    }
    d.shot_requested = false;
  }

  VkPresentInfoKHR pi{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
  pi.waitSemaphoreCount = 1;
  pi.pWaitSemaphores = &d.render_done[index];
  pi.swapchainCount = 1;
  pi.pSwapchains = &d.swapchain;
  pi.pImageIndices = &index;
  r = vkQueuePresentKHR(d.queue, &pi);
  if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR)
    d.rebuild = true;
  else
    check(r, "vkQueuePresentKHR");
  d.frame_index = (d.frame_index + 1) % kFramesInFlight;
  return true;
}

void Display::request_window_shot() {
  if (!impl_->can_read_back) throw std::runtime_error("display: this surface's images cannot be read back (no TRANSFER_SRC usage)");
  impl_->shot_requested = true;
  impl_->shot = {};
}

DisplayImage Display::take_window_shot() { return std::move(impl_->shot); }

void Display::resize(int width, int height) { glfwSetWindowSize(impl_->window, width, height); }
void Display::iconify() { glfwIconifyWindow(impl_->window); }
void Display::restore() { glfwRestoreWindow(impl_->window); }
void Display::framebuffer_size(int& width, int& height) const { glfwGetFramebufferSize(impl_->window, &width, &height); }
int Display::swapchain_recreations() const { return impl_->recreations; }
std::string Display::device_name() const { return impl_->gpu_name; }
int Display::validation_messages() const { return g_validation_messages.load(); }

}  // namespace softgi::viewer
