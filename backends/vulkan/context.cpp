// The Vulkan context: instance (with the validation layer and a debug-utils messenger when
// validation is on), device selection, memory, buffers and images, one-shot submissions with a
// fence timeout and timestamp queries.
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/backends/vulkan/loader_pin.hpp"
#include "softgi/backends/vulkan/backend.hpp"

#include <algorithm>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include <tbb/parallel_for.h>

#include "softgi/render/backend.hpp"
#include "softgi/render/frame.hpp"

#if defined(__SANITIZE_ADDRESS__)
#include <dlfcn.h>
#include <link.h>
#endif

namespace softgi::backends::vulkan {

// ---------------------------------------------------------------------------------------------
const char* to_string(VkResult r) {
  switch (r) {
#define SOFTGI_VK_CASE(x) \
  case x:                 \
    return #x;
    SOFTGI_VK_CASE(VK_SUCCESS)
    SOFTGI_VK_CASE(VK_NOT_READY)
    SOFTGI_VK_CASE(VK_TIMEOUT)
    SOFTGI_VK_CASE(VK_EVENT_SET)
    SOFTGI_VK_CASE(VK_EVENT_RESET)
    SOFTGI_VK_CASE(VK_INCOMPLETE)
    SOFTGI_VK_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    SOFTGI_VK_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    SOFTGI_VK_CASE(VK_ERROR_INITIALIZATION_FAILED)
    SOFTGI_VK_CASE(VK_ERROR_DEVICE_LOST)
    SOFTGI_VK_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    SOFTGI_VK_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    SOFTGI_VK_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    SOFTGI_VK_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    SOFTGI_VK_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    SOFTGI_VK_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    SOFTGI_VK_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    SOFTGI_VK_CASE(VK_ERROR_FRAGMENTED_POOL)
    SOFTGI_VK_CASE(VK_ERROR_UNKNOWN)
    SOFTGI_VK_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
    SOFTGI_VK_CASE(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    SOFTGI_VK_CASE(VK_ERROR_FRAGMENTATION)
#undef SOFTGI_VK_CASE
    default:
      return "VkResult(?)";
  }
}

VulkanError::VulkanError(const std::string& what, VkResult result)
    : std::runtime_error("vulkan: " + what + ": " + to_string(result) + " (" + std::to_string(static_cast<int>(result)) + ")"),
      result_(result) {}

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS) throw VulkanError(what, r);
}

// ---------------------------------------------------------------------------------------------
void ValidationLog::add(ValidationMessage m) {
  std::lock_guard<std::mutex> lock(m_);
  if (m.severity == ValidationMessage::Severity::Error) ++errors_;
  else if (m.severity == ValidationMessage::Severity::Warning) ++warnings_;
  else return;
  messages_.push_back(std::move(m));
}
std::size_t ValidationLog::errors() const {
  std::lock_guard<std::mutex> lock(m_);
  return errors_;
}
std::size_t ValidationLog::warnings() const {
  std::lock_guard<std::mutex> lock(m_);
  return warnings_;
}
std::vector<ValidationMessage> ValidationLog::messages() const {
  std::lock_guard<std::mutex> lock(m_);
  return messages_;
}
std::string ValidationLog::summary(std::size_t max_messages) const {
  std::lock_guard<std::mutex> lock(m_);
  std::ostringstream os;
  os << errors_ << " validation error(s), " << warnings_ << " warning(s)";
  for (std::size_t i = 0; i < messages_.size() && i < max_messages; ++i)
    os << "\n  [" << (messages_[i].severity == ValidationMessage::Severity::Error ? "error" : "warning") << "] "
       << messages_[i].id << ": " << messages_[i].text;
  return os.str();
}
void ValidationLog::clear() {
  std::lock_guard<std::mutex> lock(m_);
  messages_.clear();
  errors_ = warnings_ = 0;
}

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                              VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* log = static_cast<ValidationLog*>(user);
  ValidationMessage m;
  m.severity = severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT     ? ValidationMessage::Severity::Error
               : severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT ? ValidationMessage::Severity::Warning
               : severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_INFO_BIT_EXT    ? ValidationMessage::Severity::Info
                                                                             : ValidationMessage::Severity::Verbose;
  if (data) {
    m.id = data->pMessageIdName ? data->pMessageIdName : "";
    m.text = data->pMessage ? data->pMessage : "";
  }
  // Echoed as they come (the application's user sees them); tests read the log.
  if (m.severity >= ValidationMessage::Severity::Warning)
    std::fprintf(stderr, "vulkan validation %s: %s: %s\n", m.severity == ValidationMessage::Severity::Error ? "error" : "warning",
                 m.id.c_str(), m.text.c_str());
  log->add(std::move(m));
  return VK_FALSE;  // never abort the call: the test decides
}

VkDebugUtilsMessengerCreateInfoEXT messenger_info(ValidationLog* log) {
  VkDebugUtilsMessengerCreateInfoEXT ci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  ci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  ci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                   VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  ci.pfnUserCallback = debug_callback;
  ci.pUserData = log;
  return ci;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

const char* type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual-gpu";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
  }
}

// Selection preference: lower is better (GPUs before the CPU device).
int type_rank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 3;
    default: return 4;
  }
}

// The queue family used for everything: graphics + compute when there is one (the G-buffer's
// rasterisation and the compute passes share it), else compute.
int pick_queue_family(VkPhysicalDevice pd, std::uint32_t* timestamp_bits) {
  std::uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> q(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, q.data());
  int best = -1;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (!(q[i].queueFlags & VK_QUEUE_COMPUTE_BIT)) continue;
    if (best < 0 || ((q[i].queueFlags & VK_QUEUE_GRAPHICS_BIT) && !(q[best].queueFlags & VK_QUEUE_GRAPHICS_BIT)))
      best = static_cast<int>(i);
  }
  if (timestamp_bits) *timestamp_bits = best >= 0 ? q[best].timestampValidBits : 0;
  return best;
}

DeviceInfo describe_device(VkPhysicalDevice pd, int index) {
  DeviceInfo d;
  d.index = index;
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceMaintenance3Properties maint3{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
  driver.pNext = &subgroup;
  subgroup.pNext = &maint3;
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  VkPhysicalDeviceProperties base{};
  vkGetPhysicalDeviceProperties(pd, &base);
  if (base.apiVersion >= VK_API_VERSION_1_2) {
    p2.pNext = &driver;
    vkGetPhysicalDeviceProperties2(pd, &p2);
    d.driver_name = driver.driverName;
    d.driver_info = driver.driverInfo;
    d.subgroup_size = subgroup.subgroupSize;
    // gallivm's LP_MAX_TGSI_LOOP_ITERATIONS: one counter for every loop of the invocation.
    if (driver.driverID == VK_DRIVER_ID_MESA_LLVMPIPE) d.loop_iteration_limit = 65535;
    d.max_allocation_bytes = maint3.maxMemoryAllocationSize;
  }
  d.name = base.deviceName;
  d.type = base.deviceType;
  d.type_name = type_name(base.deviceType);
  d.api_version = base.apiVersion;
  d.driver_version = base.driverVersion;
  d.vendor_id = base.vendorID;
  d.device_id = base.deviceID;
  d.limits = base.limits;
  pick_queue_family(pd, &d.timestamp_valid_bits);
  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  for (std::uint32_t i = 0; i < mem.memoryHeapCount; ++i)
    if (mem.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      d.device_local_bytes = std::max<std::uint64_t>(d.device_local_bytes, mem.memoryHeaps[i].size);
  return d;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance inst) {
  std::uint32_t n = 0;
  check(vkEnumeratePhysicalDevices(inst, &n, nullptr), "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> pds(n);
  check(vkEnumeratePhysicalDevices(inst, &n, pds.data()), "vkEnumeratePhysicalDevices");
  pds.resize(n);
  return pds;
}

bool layer_available(const char* name) {
  std::uint32_t n = 0;
  if (vkEnumerateInstanceLayerProperties(&n, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(n);
  if (vkEnumerateInstanceLayerProperties(&n, layers.data()) != VK_SUCCESS) return false;
  for (const auto& l : layers)
    if (std::strcmp(l.layerName, name) == 0) return true;
  return false;
}

VkApplicationInfo app_info() {
  VkApplicationInfo a{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  a.pApplicationName = "softgi";
  a.pEngineName = "softgi";
  a.apiVersion = VK_API_VERSION_1_2;
  return a;
}


constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
constexpr std::uint32_t kQueryCapacity = 128;
constexpr std::uint32_t kSetsPerPool = 256;

}  // namespace

#if defined(__SANITIZE_ADDRESS__)
// LeakSanitizer builds: the loader dlclose()s the driver and layers when an instance goes; memory
// still referenced from an unloaded library's globals then looks leaked at exit (the globals can
// no longer be scanned) and is reported against "<unknown module>" (measured with lavapipe: 56-635
// bytes per process). Pinning every library loaded so far (RTLD_NOLOAD | RTLD_NODELETE: nothing new
// is loaded) keeps them mapped, so leak checking reports real leaks only.
namespace {
int pin_library(struct dl_phdr_info* info, std::size_t, void*) {
  if (info->dlpi_name && info->dlpi_name[0]) dlopen(info->dlpi_name, RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
  return 0;
}
}  // namespace
void pin_loaded_libraries() { dl_iterate_phdr(pin_library, nullptr); }
#else
void pin_loaded_libraries() {}
#endif

bool DeviceInfo::is_gpu() const {
  return type == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU || type == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU ||
         type == VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU;
}

std::string DeviceInfo::api_version_text() const {
  return std::to_string(VK_API_VERSION_MAJOR(api_version)) + "." + std::to_string(VK_API_VERSION_MINOR(api_version)) + "." +
         std::to_string(VK_API_VERSION_PATCH(api_version));
}

std::string DeviceInfo::describe() const {
  std::ostringstream os;
  os << name << " [" << type_name;
  if (!driver_name.empty()) os << "; " << driver_name << (driver_info.empty() ? "" : " " + driver_info);
  os << "; Vulkan " << api_version_text() << "]";
  return os.str();
}

std::vector<DeviceInfo> list_devices() {
  VkApplicationInfo a = app_info();
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &a;
  VkInstance inst = VK_NULL_HANDLE;
  check(vkCreateInstance(&ci, nullptr, &inst), "vkCreateInstance (is a Vulkan driver installed? lavapipe: mesa-vulkan-drivers)");
  pin_loaded_libraries();
  std::vector<DeviceInfo> out;
  try {
    auto pds = physical_devices(inst);
    for (std::size_t i = 0; i < pds.size(); ++i) out.push_back(describe_device(pds[i], static_cast<int>(i)));
  } catch (...) {
    vkDestroyInstance(inst, nullptr);
    throw;
  }
  vkDestroyInstance(inst, nullptr);
  return out;
}

int select_device(const std::vector<DeviceInfo>& devices, const std::string& request) {
  auto listing = [&] {
    std::string s;
    for (const auto& d : devices) s += "\n  " + std::to_string(d.index) + ": " + d.describe();
    return s.empty() ? std::string(" none") : s;
  };
  if (devices.empty()) throw std::invalid_argument("vulkan: no Vulkan device found (lavapipe: install mesa-vulkan-drivers)");
  if (request.empty()) {
    int best = 0;
    for (std::size_t i = 1; i < devices.size(); ++i)
      if (type_rank(devices[i].type) < type_rank(devices[best].type)) best = static_cast<int>(i);
    return best;
  }
  const bool numeric = std::all_of(request.begin(), request.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
  if (numeric) {
    const long idx = request.size() > 6 ? -1 : std::stol(request);
    if (idx >= 0 && idx < static_cast<long>(devices.size())) return static_cast<int>(idx);
    throw std::invalid_argument("vulkan: device index " + request + " out of range; devices:" + listing());
  }
  const std::string want = lower(request);
  for (std::size_t i = 0; i < devices.size(); ++i)
    if (lower(devices[i].name).find(want) != std::string::npos) return static_cast<int>(i);
  throw std::invalid_argument("vulkan: no device matches '" + request + "'; devices:" + listing());
}

// ---------------------------------------------------------------------------------------------
Context::Context(const ContextOptions& options) : options_(options), fence_timeout_(options.fence_timeout_seconds) {
  if (!(fence_timeout_ > 0.0) || !std::isfinite(fence_timeout_))
    throw std::invalid_argument("vulkan: fence timeout must be a positive number of seconds");
  int v = options.validation;
  if (v < 0) {
    const char* env = std::getenv("SOFTGI_VULKAN_VALIDATION");
    if (env && *env) {
      const std::string e = env;
      if (e != "0" && e != "1") throw std::invalid_argument("SOFTGI_VULKAN_VALIDATION='" + e + "' (expected 0 or 1)");
      v = e == "1";
    } else {
#ifdef NDEBUG
      v = 0;
#else
      v = 1;
#endif
    }
  }
  validation_ = v == 1;
  int unmapped = options.unmapped_device_memory;
  if (unmapped < 0) {
    const char* env = std::getenv("SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY");
    const std::string e = env ? env : "";
    if (!e.empty() && e != "0" && e != "1")
      throw std::invalid_argument("SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY='" + e + "' (expected 0 or 1)");
    unmapped = e == "1";
  }
  unmapped_device_ = unmapped == 1;
  if (validation_ && !layer_available(kValidationLayer))
    throw std::runtime_error(std::string("vulkan: validation requested but ") + kValidationLayer +
                             " is not installed (Debian: vulkan-validationlayers), or set SOFTGI_VULKAN_VALIDATION=0");

  VkApplicationInfo a = app_info();
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &a;
  std::vector<const char*> layers, exts;
  VkDebugUtilsMessengerCreateInfoEXT mi = messenger_info(log_.get());
  if (validation_) {
    layers.push_back(kValidationLayer);
    exts.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    ci.pNext = &mi;  // also covers vkCreateInstance / vkDestroyInstance themselves
  }
  ci.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  ci.ppEnabledLayerNames = layers.data();
  ci.enabledExtensionCount = static_cast<std::uint32_t>(exts.size());
  ci.ppEnabledExtensionNames = exts.data();
  check(vkCreateInstance(&ci, nullptr, &instance_), "vkCreateInstance (is a Vulkan driver installed? lavapipe: mesa-vulkan-drivers)");

  try {
    if (validation_) {
      auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
      set_name_fn_ = reinterpret_cast<PFN_vkSetDebugUtilsObjectNameEXT>(vkGetInstanceProcAddr(instance_, "vkSetDebugUtilsObjectNameEXT"));
      if (!create) throw std::runtime_error("vulkan: vkCreateDebugUtilsMessengerEXT not available");
      check(create(instance_, &mi, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
    }
    auto pds = physical_devices(instance_);
    // Before any error below can destroy the instance: the driver is loaded by now (an unknown
    // device, for one, throws before vkCreateDevice).
    pin_loaded_libraries();
    std::vector<DeviceInfo> infos;
    for (std::size_t i = 0; i < pds.size(); ++i) infos.push_back(describe_device(pds[i], static_cast<int>(i)));
    std::string request = options.device;
    if (request.empty())
      if (const char* env = std::getenv("SOFTGI_VULKAN_DEVICE")) request = env;
    const int sel = select_device(infos, request);
    physical_ = pds[sel];
    info_ = infos[sel];
    if (options.loop_iteration_limit > 0) info_.loop_iteration_limit = options.loop_iteration_limit;
    if (options.assume_no_loop_limit) info_.loop_iteration_limit = 0;
    const int qf = pick_queue_family(physical_, nullptr);
    if (qf < 0) throw std::runtime_error("vulkan: device '" + info_.name + "' has no compute queue");
    queue_family_ = static_cast<std::uint32_t>(qf);
    if (info_.api_version < VK_API_VERSION_1_2)
      throw std::runtime_error("vulkan: device '" + info_.name + "' supports Vulkan " + info_.api_version_text() +
                               "; softgi's shaders need 1.2");
    vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);

    const float prio = 1.0f;
    VkDeviceQueueCreateInfo qi{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qi.queueFamilyIndex = queue_family_;
    qi.queueCount = 1;
    qi.pQueuePriorities = &prio;
    VkPhysicalDeviceFeatures supported{};
    vkGetPhysicalDeviceFeatures(physical_, &supported);
    VkPhysicalDeviceFeatures enabled{};
    enabled.fragmentStoresAndAtomics = supported.fragmentStoresAndAtomics;
    enabled.vertexPipelineStoresAndAtomics = supported.vertexPipelineStoresAndAtomics;
    enabled.shaderInt64 = supported.shaderInt64;
    VkDeviceCreateInfo di{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    di.queueCreateInfoCount = 1;
    di.pQueueCreateInfos = &qi;
    di.pEnabledFeatures = &enabled;
    check(vkCreateDevice(physical_, &di, nullptr, &device_), "vkCreateDevice");
    pin_loaded_libraries();
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);

    VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = queue_family_;
    check(vkCreateCommandPool(device_, &pi, nullptr, &command_pool_), "vkCreateCommandPool");
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(vkCreateFence(device_, &fi, nullptr, &fence_), "vkCreateFence");
    if (info_.timestamp_valid_bits > 0 && info_.limits.timestampPeriod > 0.0f) {
      VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
      qpi.queryCount = kQueryCapacity;
      check(vkCreateQueryPool(device_, &qpi, nullptr, &query_pool_), "vkCreateQueryPool");
      query_capacity_ = kQueryCapacity;
    }
  } catch (...) {
    destroy();
    throw;
  }
}

Context::~Context() { destroy(); }

void Context::destroy() {
  settle();
  if (pending_) return;  // still running after the grace period (a hang): leak the device and instance rather than free memory in use
  if (device_ != VK_NULL_HANDLE) {
    vkDeviceWaitIdle(device_);
    clear_cache();
    for (VkDescriptorPool p : descriptor_pools_) vkDestroyDescriptorPool(device_, p, nullptr);
    descriptor_pools_.clear();
    if (query_pool_) vkDestroyQueryPool(device_, query_pool_, nullptr);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (command_pool_) vkDestroyCommandPool(device_, command_pool_, nullptr);
    query_pool_ = VK_NULL_HANDLE;
    fence_ = VK_NULL_HANDLE;
    command_pool_ = VK_NULL_HANDLE;
    vkDestroyDevice(device_, nullptr);  // the layer reports every object still alive here
    device_ = VK_NULL_HANDLE;
  }
  if (instance_ != VK_NULL_HANDLE) {
    if (messenger_ != VK_NULL_HANDLE) {
      auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
      if (destroy) destroy(instance_, messenger_, nullptr);
      messenger_ = VK_NULL_HANDLE;
    }
    vkDestroyInstance(instance_, nullptr);
    instance_ = VK_NULL_HANDLE;
  }
}

void Context::settle() {
  if (!pending_ || device_ == VK_NULL_HANDLE) return;
  // A timed-out submission may be slow rather than hung: give it at least 30 s to finish.
  const auto timeout_ns = static_cast<std::uint64_t>(std::max(fence_timeout_, 30.0) * 1e9);
  if (vkWaitForFences(device_, 1, &fence_, VK_TRUE, timeout_ns) == VK_SUCCESS) pending_ = false;
}

void Context::clear_cache() {
  std::map<std::string, std::shared_ptr<void>> old;
  {
    std::lock_guard<std::mutex> lock(cache_mutex_);
    old.swap(cache_);
  }
  old.clear();
}

void Context::set_name(VkObjectType type, std::uint64_t handle, const std::string& name) const {
  if (!set_name_fn_ || name.empty() || handle == 0) return;
  VkDebugUtilsObjectNameInfoEXT ni{VK_STRUCTURE_TYPE_DEBUG_UTILS_OBJECT_NAME_INFO_EXT};
  ni.objectType = type;
  ni.objectHandle = handle;
  ni.pObjectName = name.c_str();
  set_name_fn_(device_, &ni);
}

std::uint32_t Context::memory_type(std::uint32_t bits, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer) const {
  int best = -1;
  for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    if (!(bits & (1u << i))) continue;
    const VkMemoryPropertyFlags f = memory_.memoryTypes[i].propertyFlags;
    if ((f & want) != want) continue;
    if (best < 0 || ((f & prefer) == prefer && (memory_.memoryTypes[best].propertyFlags & prefer) != prefer)) best = static_cast<int>(i);
  }
  if (best < 0) throw std::runtime_error("vulkan: device '" + info_.name + "' has no suitable memory type");
  return static_cast<std::uint32_t>(best);
}

bool Context::device_buffers_mapped() const {
  if (unmapped_device_) return false;
  const VkMemoryPropertyFlags hv = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  const std::uint32_t type = memory_type(~0u, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT | hv);
  return (memory_.memoryTypes[type].propertyFlags & hv) == hv;
}

namespace {
std::string size_text(VkDeviceSize b) {
  std::ostringstream os;
  os << b << " bytes (" << render::format_bytes(static_cast<std::size_t>(b)) << ")";
  return os.str();
}
}  // namespace

VkDeviceMemory Context::allocate(const VkMemoryRequirements& req, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer,
                                 bool& host_visible, const std::string& what) {
  if (info_.max_allocation_bytes > 0 && req.size > info_.max_allocation_bytes)
    throw std::invalid_argument("vulkan: " + what + " needs " + size_text(req.size) + " in one allocation, more than the " +
                                "maxMemoryAllocationSize of " + size_text(info_.max_allocation_bytes) + " of device '" + info_.name + "'");
  const std::uint32_t type = memory_type(req.memoryTypeBits, want, prefer);
  const VkMemoryPropertyFlags f = memory_.memoryTypes[type].propertyFlags;
  host_visible = (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) && (f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = type;
  VkDeviceMemory mem = VK_NULL_HANDLE;
  const VkResult r = vkAllocateMemory(device_, &ai, nullptr, &mem);
  if (r != VK_SUCCESS) {
    const std::uint32_t heap = memory_.memoryTypes[type].heapIndex;
    const VkMemoryHeap& h = memory_.memoryHeaps[heap];
    throw VulkanError("vkAllocateMemory for " + what + " of " + size_text(req.size) + " from memory heap " + std::to_string(heap) +
                          " of " + size_text(h.size) + ((h.flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) ? ", device-local" : ", host") +
                          ", of device '" + info_.name + "' (buffers alive: " + size_text(allocated_) + ")",
                      r);
  }
  return mem;
}

Buffer Context::create_buffer(VkDeviceSize bytes, VkBufferUsageFlags usage, MemoryKind kind, const std::string& name) {
  const auto mib = size_text;
  if (bytes == 0) throw std::invalid_argument("vulkan: buffer '" + name + "' of size 0");
  if ((usage & VK_BUFFER_USAGE_STORAGE_BUFFER_BIT) && bytes > info_.limits.maxStorageBufferRange)
    throw std::invalid_argument("vulkan: buffer '" + name + "' needs " + mib(bytes) + ", more than the maxStorageBufferRange of " +
                                mib(info_.limits.maxStorageBufferRange) + " of device '" + info_.name + "'");
  if ((usage & VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT) && bytes > info_.limits.maxUniformBufferRange)
    throw std::invalid_argument("vulkan: buffer '" + name + "' needs " + mib(bytes) + ", more than the maxUniformBufferRange of " +
                                mib(info_.limits.maxUniformBufferRange) + " of device '" + info_.name + "'");
  if (info_.device_local_bytes > 0 && bytes > info_.device_local_bytes)
    throw std::invalid_argument("vulkan: buffer '" + name + "' needs " + mib(bytes) + ", more than the device's memory of " +
                                mib(info_.device_local_bytes));
  Buffer b;
  b.ctx_ = this;
  b.name_ = name;
  b.size_ = bytes;
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = bytes;
  bi.usage = usage | VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  // A storage buffer may also be read through texel views (Bind::texels_at).
  if (usage & VK_BUFFER_USAGE_STORAGE_BUFFER_BIT)
    bi.usage |= VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_TEXEL_BUFFER_BIT;
  bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  const std::string what = "buffer '" + name + "'";
  check(vkCreateBuffer(device_, &bi, nullptr, &b.buffer_), ("vkCreateBuffer for " + what + " of " + mib(bytes)).c_str());
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(device_, b.buffer_, &req);
  bool host = false;
  const VkMemoryPropertyFlags hv = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  if (kind == MemoryKind::Device) {
    b.memory_ = allocate(req, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT | hv, host, what);
    if (unmapped_device_) host = false;  // as a discrete GPU's (ContextOptions::unmapped_device_memory)
  } else
    b.memory_ = allocate(req, hv, hv | VK_MEMORY_PROPERTY_HOST_CACHED_BIT, host, what);
  allocated_ += static_cast<std::size_t>(bytes);
  check(vkBindBufferMemory(device_, b.buffer_, b.memory_, 0), ("vkBindBufferMemory for " + what + " of " + mib(bytes)).c_str());
  if (host) check(vkMapMemory(device_, b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_), ("vkMapMemory for " + what).c_str());
  set_name(VK_OBJECT_TYPE_BUFFER, reinterpret_cast<std::uint64_t>(b.buffer_), name);
  return b;
}

void Context::ensure_buffer(Buffer& b, VkDeviceSize bytes, VkBufferUsageFlags usage, MemoryKind kind, const std::string& name) {
  if (b && b.size() >= bytes) return;
  b = create_buffer(bytes, usage, kind, name);
}

void copy_bytes(void* dst, const void* src, std::size_t bytes) {
  constexpr std::size_t kBlock = std::size_t{1} << 20, kParallelFrom = 4 * kBlock;
  if (bytes < kParallelFrom) {
    std::memcpy(dst, src, bytes);
    return;
  }
  tbb::parallel_for(std::size_t{0}, (bytes + kBlock - 1) / kBlock, [&](std::size_t k) {
    const std::size_t at = k * kBlock;
    std::memcpy(static_cast<char*>(dst) + at, static_cast<const char*>(src) + at, std::min(kBlock, bytes - at));
  });
}

void Context::upload(const Buffer& dst, const void* src, std::size_t bytes, std::size_t dst_offset) {
  if (bytes == 0) return;
  if (dst_offset + bytes > dst.size())
    throw std::out_of_range("vulkan: upload of " + std::to_string(bytes) + " bytes at " + std::to_string(dst_offset) +
                            " into buffer '" + dst.name() + "' of " + std::to_string(dst.size()) + " bytes");
  transfer_.upload += bytes;
  if (dst.mapped()) {
    copy_bytes(static_cast<char*>(dst.mapped()) + dst_offset, src, bytes);
    return;
  }
  Buffer staging = create_buffer(bytes, 0, MemoryKind::Host, "staging upload");
  copy_bytes(staging.mapped(), src, bytes);
  submit([&](Recorder& r) { r.copy(staging, dst, bytes, 0, dst_offset); }, "upload to '" + dst.name() + "'");
}

void Context::download(const Buffer& src, void* dst, std::size_t bytes, std::size_t src_offset) {
  if (bytes == 0) return;
  if (src_offset + bytes > src.size())
    throw std::out_of_range("vulkan: download of " + std::to_string(bytes) + " bytes at " + std::to_string(src_offset) +
                            " from buffer '" + src.name() + "' of " + std::to_string(src.size()) + " bytes");
  transfer_.download += bytes;
  if (src.mapped()) {
    copy_bytes(dst, static_cast<const char*>(src.mapped()) + src_offset, bytes);
    return;
  }
  Buffer staging = create_buffer(bytes, 0, MemoryKind::Host, "staging download");
  submit([&](Recorder& r) {
    r.copy(src, staging, bytes, src_offset, 0);
    r.barrier();
  }, "download from '" + src.name() + "'");
  copy_bytes(dst, staging.mapped(), bytes);
}

// Bytes per texel of the uncompressed formats softgi and its tests use (0: not known here, and the
// driver alone judges the image's size).
std::uint64_t texel_bytes(VkFormat f) {
  switch (f) {
    case VK_FORMAT_R8_UNORM:
    case VK_FORMAT_R8_UINT:
      return 1;
    case VK_FORMAT_R8G8B8A8_UNORM:
    case VK_FORMAT_R8G8B8A8_SRGB:
    case VK_FORMAT_B8G8R8A8_UNORM:
    case VK_FORMAT_B8G8R8A8_SRGB:
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_R32_SINT:
    case VK_FORMAT_R32_UINT:
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_R16G16_SFLOAT:
      return 4;
    case VK_FORMAT_R32G32_SFLOAT:
    case VK_FORMAT_R32G32_SINT:
    case VK_FORMAT_R32G32_UINT:
    case VK_FORMAT_R16G16B16A16_SFLOAT:
      return 8;
    case VK_FORMAT_R32G32B32_SFLOAT:
      return 12;
    case VK_FORMAT_R32G32B32A32_SFLOAT:
    case VK_FORMAT_R32G32B32A32_SINT:
    case VK_FORMAT_R32G32B32A32_UINT:
      return 16;
    default:
      return 0;
  }
}

Image Context::create_image(std::uint32_t width, std::uint32_t height, VkFormat format, VkImageUsageFlags usage,
                            VkImageAspectFlags aspect, const std::string& name) {
  if (width == 0 || height == 0 || width > info_.limits.maxImageDimension2D || height > info_.limits.maxImageDimension2D)
    throw std::invalid_argument("vulkan: image '" + name + "' of " + std::to_string(width) + "x" + std::to_string(height) +
                                " outside 1.." + std::to_string(info_.limits.maxImageDimension2D) + " of device '" + info_.name + "'");
  // Sizes the device cannot hold are named here, before vkCreateImage (which validation would
  // flag, and a driver may answer with a bare VK_ERROR_OUT_OF_DEVICE_MEMORY at bind time).
  if (const std::uint64_t texel = texel_bytes(format)) {
    const std::uint64_t bytes = texel * width * height;
    const std::string what = "vulkan: image '" + name + "' (" + std::to_string(width) + "x" + std::to_string(height) + ") needs " +
                             size_text(bytes);
    if (info_.max_allocation_bytes > 0 && bytes > info_.max_allocation_bytes)
      throw std::invalid_argument(what + " in one allocation, more than the maxMemoryAllocationSize of " +
                                  size_text(info_.max_allocation_bytes) + " of device '" + info_.name + "'");
    VkImageFormatProperties fp{};
    if (vkGetPhysicalDeviceImageFormatProperties(physical_, format, VK_IMAGE_TYPE_2D, VK_IMAGE_TILING_OPTIMAL, usage, 0, &fp) ==
            VK_SUCCESS &&
        bytes > fp.maxResourceSize)
      throw std::invalid_argument(what + ", more than the maxResourceSize of " + size_text(fp.maxResourceSize) + " of device '" +
                                  info_.name + "' for its format and usage");
  }
  Image im;
  im.ctx_ = this;
  im.name_ = name;
  im.format_ = format;
  im.width_ = width;
  im.height_ = height;
  VkImageCreateInfo ii{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ii.imageType = VK_IMAGE_TYPE_2D;
  ii.format = format;
  ii.extent = {width, height, 1};
  ii.mipLevels = 1;
  ii.arrayLayers = 1;
  ii.samples = VK_SAMPLE_COUNT_1_BIT;
  ii.tiling = VK_IMAGE_TILING_OPTIMAL;
  ii.usage = usage;
  ii.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ii.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  const std::string what = "image '" + name + "' (" + std::to_string(width) + "x" + std::to_string(height) + ")";
  check(vkCreateImage(device_, &ii, nullptr, &im.image_), ("vkCreateImage for " + what).c_str());
  VkMemoryRequirements req{};
  vkGetImageMemoryRequirements(device_, im.image_, &req);
  bool host = false;
  im.memory_ = allocate(req, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, host, what);
  check(vkBindImageMemory(device_, im.image_, im.memory_, 0), ("vkBindImageMemory for " + what + " of " + size_text(req.size)).c_str());
  VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vi.image = im.image_;
  vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
  vi.format = format;
  vi.subresourceRange = {aspect, 0, 1, 0, 1};
  check(vkCreateImageView(device_, &vi, nullptr, &im.view_), "vkCreateImageView");
  set_name(VK_OBJECT_TYPE_IMAGE, reinterpret_cast<std::uint64_t>(im.image_), name);
  return im;
}

Owned<VkShaderModule> Context::create_shader_module(std::span<const std::uint32_t> spirv, const std::string& name) {
  if (spirv.size() < 5 || spirv[0] != 0x07230203u)
    throw std::invalid_argument("vulkan: shader '" + name + "' is not SPIR-V");
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = spirv.size() * sizeof(std::uint32_t);
  ci.pCode = spirv.data();
  VkShaderModule m = VK_NULL_HANDLE;
  check(vkCreateShaderModule(device_, &ci, nullptr, &m), ("vkCreateShaderModule '" + name + "'").c_str());
  set_name(VK_OBJECT_TYPE_SHADER_MODULE, reinterpret_cast<std::uint64_t>(m), name);
  VkDevice dev = device_;
  return Owned<VkShaderModule>(m, [dev](VkShaderModule x) { vkDestroyShaderModule(dev, x, nullptr); });
}

VkDescriptorSet Context::allocate_set(VkDescriptorSetLayout layout) {
  for (;;) {
    if (pool_in_use_ == descriptor_pools_.size()) {
      const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kSetsPerPool * 8},
                                            {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kSetsPerPool},
                                            {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, kSetsPerPool * 2},
                                            {VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, kSetsPerPool},
                                            {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kSetsPerPool * 2},
                                            {VK_DESCRIPTOR_TYPE_SAMPLER, kSetsPerPool},
                                            {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kSetsPerPool * 4},
                                            {VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER, kSetsPerPool * 2}};
      VkDescriptorPoolCreateInfo ci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
      ci.maxSets = kSetsPerPool;
      ci.poolSizeCount = static_cast<std::uint32_t>(std::size(sizes));
      ci.pPoolSizes = sizes;
      VkDescriptorPool p = VK_NULL_HANDLE;
      check(vkCreateDescriptorPool(device_, &ci, nullptr, &p), "vkCreateDescriptorPool");
      descriptor_pools_.push_back(p);
    }
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = descriptor_pools_[pool_in_use_];
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &layout;
    VkDescriptorSet set = VK_NULL_HANDLE;
    const VkResult r = vkAllocateDescriptorSets(device_, &ai, &set);
    if (r == VK_SUCCESS) return set;
    if (r != VK_ERROR_OUT_OF_POOL_MEMORY && r != VK_ERROR_FRAGMENTED_POOL) check(r, "vkAllocateDescriptorSets");
    ++pool_in_use_;
  }
}

SubmitResult Context::submit(const std::function<void(Recorder&)>& record, const std::string& what) {
  std::lock_guard<std::mutex> lock(submit_mutex_);
  if (lost_) throw std::runtime_error("vulkan: device '" + info_.name + "' is unusable after an earlier submission timed out");
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = command_pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  check(vkAllocateCommandBuffers(device_, &ai, &cmd), "vkAllocateCommandBuffers");
  VkDevice dev = device_;
  VkCommandPool pool = command_pool_;
  Owned<VkCommandBuffer> owned(cmd, [dev, pool](VkCommandBuffer c) { vkFreeCommandBuffers(dev, pool, 1, &c); });
  auto reset_pools = [this] {
    for (VkDescriptorPool p : descriptor_pools_) vkResetDescriptorPool(device_, p, 0);
    pool_in_use_ = 0;
  };
  Recorder rec(*this, cmd);
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
  queries_used_ = 0;
  if (query_pool_) {
    vkCmdResetQueryPool(cmd, query_pool_, 0, query_capacity_);
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, query_pool_, queries_used_++);
  }
  try {
    record(rec);
    if (rec.timer_open_) throw std::logic_error("vulkan: submission '" + what + "' left a timer open");
  } catch (...) {
    vkEndCommandBuffer(cmd);
    for (VkBufferView v : rec.views_) vkDestroyBufferView(device_, v, nullptr);
    reset_pools();
    throw;
  }
  const std::uint32_t end_query = queries_used_;
  if (query_pool_) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, query_pool_, queries_used_++);
  check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  check(vkResetFences(device_, 1, &fence_), "vkResetFences");
  const auto t_submit = std::chrono::steady_clock::now();
  if (const VkResult r = vkQueueSubmit(queue_, 1, &si, fence_); r != VK_SUCCESS) {
    for (VkBufferView v : rec.views_) vkDestroyBufferView(device_, v, nullptr);
    reset_pools();
    check(r, ("vkQueueSubmit '" + what + "'").c_str());
  }
  const auto timeout_ns = static_cast<std::uint64_t>(fence_timeout_ * 1e9);
  const VkResult w = vkWaitForFences(device_, 1, &fence_, VK_TRUE, timeout_ns);
  auto destroy_views = [&] {
    for (VkBufferView v : rec.views_) vkDestroyBufferView(device_, v, nullptr);
    rec.views_.clear();
  };
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_submit).count();
  if (w == VK_TIMEOUT) {
    std::ostringstream os;
    os << "submission '" << what << "' did not complete within " << fence_timeout_ << " s on device '" << info_.name << "'";
    // The command buffer may still be executing: it must not be freed, and the context is unusable.
    (void)owned.release();
    rec.views_.clear();  // may still be in use: left to the device's destruction
    lost_ = true;
    pending_ = true;
    throw VulkanError(os.str(), w);
  }
  destroy_views();
  check(w, ("vkWaitForFences '" + what + "'").c_str());
  reset_pools();
  SubmitResult res;
  res.wait_seconds = waited;
  wait_total_ += waited;
  if (query_pool_) {
    std::vector<std::uint64_t> ts(queries_used_);
    check(vkGetQueryPoolResults(device_, query_pool_, 0, queries_used_, ts.size() * sizeof(std::uint64_t), ts.data(),
                                sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
          "vkGetQueryPoolResults");
    const std::uint64_t mask =
        info_.timestamp_valid_bits >= 64 ? ~std::uint64_t{0} : ((std::uint64_t{1} << info_.timestamp_valid_bits) - 1);
    const double period = static_cast<double>(info_.limits.timestampPeriod) * 1e-9;
    auto span = [&](std::uint32_t a, std::uint32_t b) { return static_cast<double>(((ts[b] & mask) - (ts[a] & mask)) & mask) * period; };
    res.gpu_seconds = span(0, end_query);
    for (std::size_t i = 0; i < rec.timer_labels_.size(); ++i)
      res.timers.emplace_back(rec.timer_labels_[i], span(static_cast<std::uint32_t>(1 + 2 * i), static_cast<std::uint32_t>(2 + 2 * i)));
    gpu_total_ += res.gpu_seconds;
  }
  ++submissions_;
  return res;
}

void Context::leak_buffer_for_test() {
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = 256;
  bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  VkBuffer b = VK_NULL_HANDLE;
  check(vkCreateBuffer(device_, &bi, nullptr, &b), "vkCreateBuffer");
  set_name(VK_OBJECT_TYPE_BUFFER, reinterpret_cast<std::uint64_t>(b), "deliberately leaked (test)");
  leaked_for_test_.push_back(b);
}

// ---------------------------------------------------------------------------------------------
Buffer::~Buffer() { release(); }
Buffer::Buffer(Buffer&& o) noexcept
    : ctx_(std::exchange(o.ctx_, nullptr)),
      buffer_(std::exchange(o.buffer_, VK_NULL_HANDLE)),
      memory_(std::exchange(o.memory_, VK_NULL_HANDLE)),
      size_(std::exchange(o.size_, 0)),
      mapped_(std::exchange(o.mapped_, nullptr)),
      name_(std::move(o.name_)) {}
Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    release();
    ctx_ = std::exchange(o.ctx_, nullptr);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
    name_ = std::move(o.name_);
  }
  return *this;
}
void Buffer::release() {
  if (!ctx_) return;
  ctx_->settle();
  VkDevice dev = ctx_->device();
  if (buffer_) vkDestroyBuffer(dev, buffer_, nullptr);
  if (memory_) {
    vkFreeMemory(dev, memory_, nullptr);
    ctx_->note_free(size_);
  }
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  size_ = 0;
  ctx_ = nullptr;
}

Image::~Image() { release(); }
Image::Image(Image&& o) noexcept
    : ctx_(std::exchange(o.ctx_, nullptr)),
      image_(std::exchange(o.image_, VK_NULL_HANDLE)),
      view_(std::exchange(o.view_, VK_NULL_HANDLE)),
      memory_(std::exchange(o.memory_, VK_NULL_HANDLE)),
      format_(o.format_),
      width_(o.width_),
      height_(o.height_),
      name_(std::move(o.name_)) {}
Image& Image::operator=(Image&& o) noexcept {
  if (this != &o) {
    release();
    ctx_ = std::exchange(o.ctx_, nullptr);
    image_ = std::exchange(o.image_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    format_ = o.format_;
    width_ = o.width_;
    height_ = o.height_;
    name_ = std::move(o.name_);
  }
  return *this;
}
void Image::release() {
  if (!ctx_) return;
  ctx_->settle();
  VkDevice dev = ctx_->device();
  if (view_) vkDestroyImageView(dev, view_, nullptr);
  if (image_) vkDestroyImage(dev, image_, nullptr);
  if (memory_) vkFreeMemory(dev, memory_, nullptr);
  view_ = VK_NULL_HANDLE;
  image_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  ctx_ = nullptr;
}

// ---------------------------------------------------------------------------------------------
Context& context_of(render::FrameContext& frame) {
  auto* c = dynamic_cast<Context*>(frame.device);
  if (!c) throw std::logic_error("vulkan: this frame is not executed by the Vulkan backend (no Vulkan context)");
  return *c;
}

std::string Context::backend_name() const { return kBackendName; }

}  // namespace softgi::backends::vulkan
