// For every program that creates Vulkan instances under LeakSanitizer (the backend's contexts, the
// viewer's display): keeps the libraries the loader has opened (driver, layers, window-system
// libraries) mapped after their instance goes, so that memory their globals still hold is not
// reported as leaked from "<unknown module>" at exit. Does nothing in other builds.
#pragma once

namespace softgi::backends::vulkan {

// Call after vkCreateInstance / vkCreateDevice / surface creation: pins what is loaded so far.
void pin_loaded_libraries();

}  // namespace softgi::backends::vulkan
