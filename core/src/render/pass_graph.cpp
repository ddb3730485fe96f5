#include "softgi/render/pass_graph.hpp"

#include <algorithm>
#include <stdexcept>

namespace softgi::render {

std::map<std::string, PassFn> host_impl(PassFn fn) { return {{kHostImpl, std::move(fn)}}; }

int PassGraph::add(PassDesc pass) {
  for (const auto& p : passes_)
    if (p.name == pass.name) throw std::invalid_argument("pass graph: two passes named '" + pass.name + "'");
  passes_.push_back(std::move(pass));
  return static_cast<int>(passes_.size()) - 1;
}

CompiledGraph PassGraph::compile(const std::vector<std::string>& outputs, const std::set<std::string>& empty) const {
  const int n = static_cast<int>(passes_.size());
  std::map<std::string, int> writer;
  for (int i = 0; i < n; ++i)
    for (const auto& w : passes_[i].writes) {
      if (writer.count(w))
        throw std::invalid_argument("pass graph: resource '" + w + "' written by both '" + passes_[writer[w]].name +
                                    "' and '" + passes_[i].name + "'");
      writer[w] = i;
    }
  auto check_read = [&](const PassDesc& p, const std::string& r) {
    if (!writer.count(r) && !inputs_.count(r))
      throw std::invalid_argument("pass graph: pass '" + p.name + "' reads '" + r + "', which no pass writes and is no input");
  };
  // An optional read that nothing writes is simply empty (e.g. compose's "indirect" for a technique
  // without indirect light); a required one is an error.
  std::set<std::string> absent;
  for (const auto& p : passes_) {
    for (const auto& r : p.reads) check_read(p, r);
    for (const auto& r : p.optional_reads)
      if (!writer.count(r) && !inputs_.count(r)) absent.insert(r);
  }

  // Forward: which passes can run (no required read empty); their outputs are live.
  CompiledGraph g;
  g.empty = empty;
  g.empty.insert(absent.begin(), absent.end());
  std::vector<int> state(n, 0);  // 0 unvisited, 1 runnable, 2 pruned (empty input), 3 being visited
  std::vector<std::string> reason(n);
  std::function<bool(int)> runnable = [&](int i) -> bool {
    if (state[i] == 3) throw std::invalid_argument("pass graph: cycle through pass '" + passes_[i].name + "'");
    if (state[i]) return state[i] == 1;
    state[i] = 3;
    auto is_empty = [&](const std::string& r) -> bool {
      if (empty.count(r) || absent.count(r)) return true;
      auto w = writer.find(r);
      if (w == writer.end()) return false;  // an input
      return !runnable(w->second);
    };
    int result = 1;
    for (const auto& r : passes_[i].reads)
      if (is_empty(r) && result == 1) {
        result = 2;
        reason[i] = "required input '" + r + "' is empty";
      }
    for (const auto& r : passes_[i].optional_reads) is_empty(r);  // visits writers (and finds cycles)
    state[i] = result;
    return result == 1;
  };
  for (int i = 0; i < n; ++i) runnable(i);
  for (int i = 0; i < n; ++i)
    if (state[i] == 2)
      for (const auto& w : passes_[i].writes) g.empty.insert(w);

  // Backward from the outputs: a pass is needed when it writes a needed, non-empty resource.
  std::vector<bool> needed(n, false);
  std::vector<std::string> work;
  for (const auto& o : outputs) {
    if (!writer.count(o) && !inputs_.count(o)) throw std::invalid_argument("pass graph: unknown output '" + o + "'");
    work.push_back(o);
  }
  std::set<std::string> seen;
  while (!work.empty()) {
    std::string r = work.back();
    work.pop_back();
    if (!seen.insert(r).second) continue;
    auto w = writer.find(r);
    if (w == writer.end() || state[w->second] != 1) continue;
    if (!needed[w->second]) {
      needed[w->second] = true;
      for (const auto& rr : passes_[w->second].reads) work.push_back(rr);
      for (const auto& rr : passes_[w->second].optional_reads)
        if (!g.empty.count(rr)) work.push_back(rr);
    }
  }

  // Dependency order among the needed passes (insertion order breaks ties).
  std::vector<int> done(n, 0);
  std::function<void(int)> visit = [&](int i) {
    if (done[i]) return;
    done[i] = 1;
    auto dep = [&](const std::string& r) {
      auto w = writer.find(r);
      if (w != writer.end() && needed[w->second]) visit(w->second);
    };
    for (const auto& r : passes_[i].reads) dep(r);
    for (const auto& r : passes_[i].optional_reads) dep(r);
    g.order.push_back(i);
  };
  for (int i = 0; i < n; ++i)
    if (needed[i]) visit(i);
  for (int i : g.order)
    for (const auto& w : passes_[i].writes) g.live.insert(w);
  for (int i = 0; i < n; ++i) {
    if (needed[i]) continue;
    g.pruned.push_back({passes_[i].name, state[i] == 2 ? reason[i] : "no requested output depends on it"});
  }
  for (const auto& [resource, message] : empty_warnings_)
    if (g.empty.count(resource)) g.warnings.push_back(message);
  return g;
}

}  // namespace softgi::render
