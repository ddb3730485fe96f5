// The message of the std::invalid_argument a callable throws, or "(nothing thrown)": tests then search
// it for the words that name the bad input.
#pragma once

#include <stdexcept>
#include <string>

namespace softgi::test {

template <class F>
std::string thrown_message(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(nothing thrown)";
}

}  // namespace softgi::test
