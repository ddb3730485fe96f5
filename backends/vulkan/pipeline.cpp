// SPIR-V reflection (descriptor bindings, push-constant block size, workgroup size), pipeline
// layouts derived from it, compute pipelines, and command recording.
#include <algorithm>
#include <array>
#include <map>
#include <sstream>
#include <tuple>
#include <unordered_map>

#include "softgi/backends/vulkan/context.hpp"

namespace softgi::backends::vulkan {

namespace {

// SPIR-V opcodes, decorations and storage classes used here (SPIR-V 1.6 specification, section 3).
enum Op : std::uint32_t {
  OpName = 5,
  OpEntryPoint = 15,
  OpExecutionMode = 16,
  OpTypeBool = 20,
  OpTypeInt = 21,
  OpTypeFloat = 22,
  OpTypeVector = 23,
  OpTypeMatrix = 24,
  OpTypeImage = 25,
  OpTypeSampler = 26,
  OpTypeSampledImage = 27,
  OpTypeArray = 28,
  OpTypeRuntimeArray = 29,
  OpTypeStruct = 30,
  OpTypePointer = 32,
  OpConstant = 43,
  OpVariable = 59,
  OpDecorate = 71,
  OpMemberDecorate = 72,
  OpTypeAccelerationStructureKHR = 5341,
};
enum Decoration : std::uint32_t {
  DecBlock = 2,
  DecBufferBlock = 3,
  DecArrayStride = 6,
  DecMatrixStride = 7,
  DecBinding = 33,
  DecDescriptorSet = 34,
  DecOffset = 35,
};
enum StorageClass : std::uint32_t {
  ScUniformConstant = 0,
  ScUniform = 2,
  ScPushConstant = 9,
  ScStorageBuffer = 12,
};

struct TypeInfo {
  std::uint32_t op = 0;
  std::vector<std::uint32_t> args;  // operands after the result id
};

std::string read_string(std::span<const std::uint32_t> w, std::size_t& pos, std::size_t end) {
  std::string s;
  while (pos < end) {
    const std::uint32_t word = w[pos++];
    for (int b = 0; b < 4; ++b) {
      const char c = static_cast<char>((word >> (8 * b)) & 0xffu);
      if (c == '\0') return s;
      s.push_back(c);
    }
  }
  return s;
}

}  // namespace

ShaderReflection reflect_spirv(std::span<const std::uint32_t> w) {
  if (w.size() < 5 || w[0] != 0x07230203u) throw std::invalid_argument("spirv: not a SPIR-V module (bad magic or too short)");
  ShaderReflection out;
  std::unordered_map<std::uint32_t, TypeInfo> types;
  std::unordered_map<std::uint32_t, std::uint32_t> constants;
  std::unordered_map<std::uint32_t, std::string> names;
  std::unordered_map<std::uint32_t, std::uint32_t> binding, set, array_stride;
  std::unordered_map<std::uint32_t, bool> buffer_block;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> member_offset, member_matrix_stride;
  struct Var {
    std::uint32_t id, pointer_type, storage;
  };
  std::vector<Var> vars;
  bool have_entry = false;
  std::size_t pos = 5;
  while (pos < w.size()) {
    const std::uint32_t count = w[pos] >> 16, op = w[pos] & 0xffffu;
    if (count == 0 || pos + count > w.size()) throw std::invalid_argument("spirv: truncated instruction at word " + std::to_string(pos));
    const std::size_t end = pos + count;
    auto arg = [&](std::size_t i) { return w[pos + 1 + i]; };
    switch (op) {
      case OpName: {
        std::size_t p = pos + 2;
        names[arg(0)] = read_string(w, p, end);
        break;
      }
      case OpEntryPoint:
        if (!have_entry) {
          have_entry = true;
          const std::uint32_t model = arg(0);
          switch (model) {
            case 0: out.stage = VK_SHADER_STAGE_VERTEX_BIT; break;
            case 1: out.stage = VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT; break;
            case 2: out.stage = VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT; break;
            case 3: out.stage = VK_SHADER_STAGE_GEOMETRY_BIT; break;
            case 4: out.stage = VK_SHADER_STAGE_FRAGMENT_BIT; break;
            case 5: out.stage = VK_SHADER_STAGE_COMPUTE_BIT; break;
            default: throw std::invalid_argument("spirv: unsupported execution model " + std::to_string(model));
          }
          std::size_t p = pos + 3;
          out.entry_point = read_string(w, p, end);
        }
        break;
      case OpExecutionMode:
        if (arg(1) == 17 && count >= 6) {  // LocalSize x y z
          out.local_size[0] = arg(2);
          out.local_size[1] = arg(3);
          out.local_size[2] = arg(4);
        }
        break;
      case OpTypeBool: case OpTypeInt: case OpTypeFloat: case OpTypeVector: case OpTypeMatrix: case OpTypeImage:
      case OpTypeSampler: case OpTypeSampledImage: case OpTypeArray: case OpTypeRuntimeArray: case OpTypeStruct:
      case OpTypePointer: case OpTypeAccelerationStructureKHR: {
        TypeInfo t;
        t.op = op;
        for (std::size_t i = pos + 2; i < end; ++i) t.args.push_back(w[i]);
        types[arg(0)] = std::move(t);
        break;
      }
      case OpConstant:
        if (count >= 4) constants[arg(1)] = arg(2);
        break;
      case OpVariable:
        vars.push_back({arg(1), arg(0), arg(2)});
        break;
      case OpDecorate:
        if (count >= 3) {
          const std::uint32_t target = arg(0), dec = arg(1);
          if (dec == DecBinding && count >= 4) binding[target] = arg(2);
          if (dec == DecDescriptorSet && count >= 4) set[target] = arg(2);
          if (dec == DecArrayStride && count >= 4) array_stride[target] = arg(2);
          if (dec == DecBufferBlock) buffer_block[target] = true;
        }
        break;
      case OpMemberDecorate:
        if (count >= 5 && arg(2) == DecOffset) member_offset[{arg(0), arg(1)}] = arg(3);
        if (count >= 5 && arg(2) == DecMatrixStride) member_matrix_stride[{arg(0), arg(1)}] = arg(3);
        break;
      default:
        break;
    }
    pos = end;
  }
  if (!have_entry) throw std::invalid_argument("spirv: module has no entry point");

  auto type_of = [&](std::uint32_t id) -> const TypeInfo& {
    auto it = types.find(id);
    if (it == types.end()) throw std::invalid_argument("spirv: unknown type id " + std::to_string(id));
    return it->second;
  };
  // Size in bytes of a type inside an explicitly laid out block (std140/std430/push constants).
  std::function<std::uint32_t(std::uint32_t, std::uint32_t)> size_of = [&](std::uint32_t id, std::uint32_t matrix_stride) -> std::uint32_t {
    const TypeInfo& t = type_of(id);
    switch (t.op) {
      case OpTypeBool: return 4;
      case OpTypeInt:
      case OpTypeFloat: return t.args.at(0) / 8;
      case OpTypeVector: return t.args.at(1) * size_of(t.args.at(0), 0);
      case OpTypeMatrix: return t.args.at(1) * (matrix_stride ? matrix_stride : size_of(t.args.at(0), 0));
      case OpTypeArray: {
        const std::uint32_t len = constants.count(t.args.at(1)) ? constants[t.args.at(1)] : 0;
        const std::uint32_t stride = array_stride.count(id) ? array_stride[id] : size_of(t.args.at(0), 0);
        return len * stride;
      }
      case OpTypeRuntimeArray: return 0;
      case OpTypeStruct: {
        std::uint32_t sz = 0;
        for (std::uint32_t m = 0; m < t.args.size(); ++m) {
          const std::uint32_t off = member_offset.count({id, m}) ? member_offset[{id, m}] : 0;
          const std::uint32_t ms = member_matrix_stride.count({id, m}) ? member_matrix_stride[{id, m}] : 0;
          sz = std::max(sz, off + size_of(t.args[m], ms));
        }
        return sz;
      }
      default: throw std::invalid_argument("spirv: type id " + std::to_string(id) + " (op " + std::to_string(t.op) + ") has no size");
    }
  };

  for (const Var& v : vars) {
    const TypeInfo& ptr = type_of(v.pointer_type);
    if (ptr.op != OpTypePointer) continue;
    std::uint32_t pointee = ptr.args.at(1);
    if (v.storage == ScPushConstant) {
      out.push_constant_size = std::max(out.push_constant_size, size_of(pointee, 0));
      continue;
    }
    if (v.storage != ScUniformConstant && v.storage != ScUniform && v.storage != ScStorageBuffer) continue;
    if (!binding.count(v.id)) continue;
    ReflectedBinding b;
    b.binding = binding[v.id];
    b.set = set.count(v.id) ? set[v.id] : 0;
    b.stages = static_cast<VkShaderStageFlags>(out.stage);
    b.name = names.count(v.id) && !names[v.id].empty() ? names[v.id] : (names.count(pointee) ? names[pointee] : "");
    const TypeInfo* t = &type_of(pointee);
    if (t->op == OpTypeArray) {
      b.count = constants.count(t->args.at(1)) ? constants[t->args.at(1)] : 1;
      pointee = t->args.at(0);
      t = &type_of(pointee);
    } else if (t->op == OpTypeRuntimeArray) {
      throw std::invalid_argument("spirv: binding " + std::to_string(b.binding) + " ('" + b.name +
                                  "') is a runtime-sized descriptor array, which softgi does not use");
    }
    if (v.storage == ScStorageBuffer) {
      b.type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    } else if (v.storage == ScUniform) {
      b.type = buffer_block.count(pointee) ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER : VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    } else if (t->op == OpTypeSampledImage) {
      // A samplerBuffer is a uniform texel buffer (the image operand's Dim is Buffer = 5).
      const TypeInfo& image = type_of(t->args.at(0));
      b.type = image.op == OpTypeImage && image.args.at(1) == 5 ? VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER
                                                                  : VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    } else if (t->op == OpTypeSampler) {
      b.type = VK_DESCRIPTOR_TYPE_SAMPLER;
    } else if (t->op == OpTypeAccelerationStructureKHR) {
      b.type = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
    } else if (t->op == OpTypeImage) {
      const std::uint32_t dim = t->args.at(1), sampled = t->args.at(5);
      if (dim == 5) b.type = sampled == 2 ? VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER : VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
      else if (dim == 6) b.type = VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT;
      else b.type = sampled == 2 ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE : VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE;
    } else {
      throw std::invalid_argument("spirv: binding " + std::to_string(b.binding) + " ('" + b.name + "') has a resource type softgi does not know");
    }
    out.bindings.push_back(std::move(b));
  }
  std::sort(out.bindings.begin(), out.bindings.end(),
            [](const ReflectedBinding& a, const ReflectedBinding& b) { return std::tie(a.set, a.binding) < std::tie(b.set, b.binding); });
  return out;
}

// ---------------------------------------------------------------------------------------------
PipelineLayout::PipelineLayout(Context& ctx, const std::vector<ShaderReflection>& stages, const std::string& name)
    : ctx_(ctx), name_(name) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, ReflectedBinding> merged;
  for (const auto& st : stages) {
    for (const auto& b : st.bindings) {
      auto [it, inserted] = merged.try_emplace({b.set, b.binding}, b);
      if (!inserted) {
        if (it->second.type != b.type)
          throw std::invalid_argument("vulkan: pipeline '" + name + "': set " + std::to_string(b.set) + " binding " +
                                      std::to_string(b.binding) + " is declared with different descriptor types by two stages");
        it->second.count = std::max(it->second.count, b.count);
        it->second.stages |= b.stages;
      }
    }
    if (st.push_constant_size > 0) {
      push_size_ = std::max(push_size_, st.push_constant_size);
      push_stages_ |= static_cast<VkShaderStageFlags>(st.stage);
    }
  }
  if (push_size_ > ctx.device_info().limits.maxPushConstantsSize)
    throw std::invalid_argument("vulkan: pipeline '" + name + "' needs " + std::to_string(push_size_) +
                                " bytes of push constants, more than the device's " +
                                std::to_string(ctx.device_info().limits.maxPushConstantsSize));
  std::uint32_t nsets = 0;
  for (const auto& [k, b] : merged) {
    nsets = std::max(nsets, b.set + 1);
    bindings_.push_back(b);
  }
  VkDevice dev = ctx.device();
  try {
    for (std::uint32_t s = 0; s < nsets; ++s) {
      std::vector<VkDescriptorSetLayoutBinding> lb;
      for (const auto& b : bindings_)
        if (b.set == s) lb.push_back({b.binding, b.type, b.count, b.stages, nullptr});
      VkDescriptorSetLayoutCreateInfo ci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
      ci.bindingCount = static_cast<std::uint32_t>(lb.size());
      ci.pBindings = lb.data();
      VkDescriptorSetLayout l = VK_NULL_HANDLE;
      check(vkCreateDescriptorSetLayout(dev, &ci, nullptr, &l), "vkCreateDescriptorSetLayout");
      sets_.push_back(l);
    }
    VkPushConstantRange range{push_stages_, 0, push_size_};
    VkPipelineLayoutCreateInfo pi{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pi.setLayoutCount = static_cast<std::uint32_t>(sets_.size());
    pi.pSetLayouts = sets_.data();
    pi.pushConstantRangeCount = push_size_ > 0 ? 1 : 0;
    pi.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(dev, &pi, nullptr, &layout_), "vkCreatePipelineLayout");
  } catch (...) {
    for (auto l : sets_) vkDestroyDescriptorSetLayout(dev, l, nullptr);
    throw;
  }
  ctx.set_name(VK_OBJECT_TYPE_PIPELINE_LAYOUT, reinterpret_cast<std::uint64_t>(layout_), name);
}

PipelineLayout::~PipelineLayout() {
  ctx_.settle();
  VkDevice dev = ctx_.device();
  if (layout_) vkDestroyPipelineLayout(dev, layout_, nullptr);
  for (auto l : sets_) vkDestroyDescriptorSetLayout(dev, l, nullptr);
}

// ---------------------------------------------------------------------------------------------
ComputePipeline::ComputePipeline(Context& ctx, std::span<const std::uint32_t> spirv, const std::string& name,
                                 const std::vector<SpecConstant>& spec)
    : ctx_(ctx), name_(name), reflection_(reflect_spirv(spirv)) {
  if (reflection_.stage != VK_SHADER_STAGE_COMPUTE_BIT)
    throw std::invalid_argument("vulkan: pipeline '" + name + "': the shader is not a compute shader");
  const auto& lim = ctx.device_info().limits;
  const std::uint64_t inv = std::uint64_t{reflection_.local_size[0]} * reflection_.local_size[1] * reflection_.local_size[2];
  if (inv > lim.maxComputeWorkGroupInvocations)
    throw std::invalid_argument("vulkan: pipeline '" + name + "': workgroup of " + std::to_string(inv) +
                                " invocations, more than the device's " + std::to_string(lim.maxComputeWorkGroupInvocations));
  layout_ = std::make_unique<PipelineLayout>(ctx, std::vector<ShaderReflection>{reflection_}, name);
  Owned<VkShaderModule> module = ctx.create_shader_module(spirv, name);
  std::vector<VkSpecializationMapEntry> entries;
  std::vector<std::uint32_t> values;
  for (std::size_t i = 0; i < spec.size(); ++i) {
    entries.push_back({spec[i].id, static_cast<std::uint32_t>(i * sizeof(std::uint32_t)), sizeof(std::uint32_t)});
    values.push_back(spec[i].value);
  }
  VkSpecializationInfo si{static_cast<std::uint32_t>(entries.size()), entries.data(), values.size() * sizeof(std::uint32_t),
                          values.data()};
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = module.get();
  ci.stage.pName = reflection_.entry_point.c_str();
  ci.stage.pSpecializationInfo = spec.empty() ? nullptr : &si;
  ci.layout = layout_->handle();
  check(vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline_),
        ("vkCreateComputePipelines '" + name + "'").c_str());
  ctx.set_name(VK_OBJECT_TYPE_PIPELINE, reinterpret_cast<std::uint64_t>(pipeline_), name);
}

ComputePipeline::~ComputePipeline() {
  ctx_.settle();
  if (pipeline_) vkDestroyPipeline(ctx_.device(), pipeline_, nullptr);
}

std::uint32_t ComputePipeline::groups_x(std::size_t items) const {
  const std::size_t l = reflection_.local_size[0];
  const std::size_t g = (items + l - 1) / l;
  if (g > ctx_.device_info().limits.maxComputeWorkGroupCount[0])
    throw std::invalid_argument("vulkan: pipeline '" + name_ + "': " + std::to_string(items) + " items need " + std::to_string(g) +
                                " workgroups, more than the device's maxComputeWorkGroupCount[0] = " +
                                std::to_string(ctx_.device_info().limits.maxComputeWorkGroupCount[0]));
  return static_cast<std::uint32_t>(g);
}

// ---------------------------------------------------------------------------------------------
namespace {
bool is_buffer_type(VkDescriptorType t) {
  return t == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER || t == VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
}
bool is_texel_type(VkDescriptorType t) {
  return t == VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER || t == VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER;
}
bool is_image_type(VkDescriptorType t) {
  return t == VK_DESCRIPTOR_TYPE_STORAGE_IMAGE || t == VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE ||
         t == VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER || t == VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT;
}
}  // namespace

VkDescriptorSet Recorder::descriptor_set(const PipelineLayout& layout, std::uint32_t set, const std::vector<Bind>& binds) {
  auto where = [&](std::uint32_t b) {
    return "vulkan: pipeline '" + layout.name() + "' set " + std::to_string(set) + " binding " + std::to_string(b);
  };
  for (const Bind& b : binds) {
    if (b.set != set) continue;
    bool declared = false;
    for (const auto& rb : layout.bindings()) declared = declared || (rb.set == set && rb.binding == b.binding);
    if (!declared) throw std::invalid_argument(where(b.binding) + ": given a resource, but the shader declares no such binding");
  }
  const VkDescriptorSet ds = ctx_.allocate_set(layout.set_layout(set));
  std::vector<VkWriteDescriptorSet> writes;
  std::vector<VkDescriptorBufferInfo> buffers;
  std::vector<VkDescriptorImageInfo> images;
  std::vector<VkBufferView> texel_views;
  buffers.reserve(layout.bindings().size());
  images.reserve(layout.bindings().size());
  texel_views.reserve(layout.bindings().size());
  for (const auto& rb : layout.bindings()) {
    if (rb.set != set) continue;
    const Bind* found = nullptr;
    for (const Bind& b : binds)
      if (b.set == set && b.binding == rb.binding) found = &b;
    if (!found) throw std::invalid_argument(where(rb.binding) + (rb.name.empty() ? "" : " ('" + rb.name + "')") + ": no resource given");
    VkWriteDescriptorSet wr{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    wr.dstSet = ds;
    wr.dstBinding = rb.binding;
    wr.descriptorCount = 1;
    wr.descriptorType = rb.type;
    if (is_buffer_type(rb.type)) {
      if (!found->buffer || !*found->buffer) throw std::invalid_argument(where(rb.binding) + ": expects a buffer");
      buffers.push_back({found->buffer->handle(), found->offset, found->range});
      wr.pBufferInfo = &buffers.back();
    } else if (is_texel_type(rb.type)) {
      if (!found->buffer || !*found->buffer || found->texel_format == VK_FORMAT_UNDEFINED)
        throw std::invalid_argument(where(rb.binding) + ": expects a buffer with a texel format (Bind::texels_at)");
      const std::uint64_t texel = texel_bytes(found->texel_format);
      const std::uint64_t bytes = found->range == VK_WHOLE_SIZE ? found->buffer->size() - found->offset : found->range;
      if (texel > 0 && bytes < texel)
        throw std::invalid_argument(where(rb.binding) + ": buffer '" + found->buffer->name() + "' holds " + std::to_string(bytes) +
                                    " bytes, less than one texel of " + std::to_string(texel));
      if (texel > 0 && bytes / texel > ctx_.device_info().limits.maxTexelBufferElements)
        throw std::invalid_argument(where(rb.binding) + ": buffer '" + found->buffer->name() + "' holds " + std::to_string(bytes / texel) +
                                    " texels, more than the maxTexelBufferElements of " +
                                    std::to_string(ctx_.device_info().limits.maxTexelBufferElements) + " of device '" +
                                    ctx_.device_info().name + "'");
      VkBufferViewCreateInfo vi{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
      vi.buffer = found->buffer->handle();
      vi.format = found->texel_format;
      vi.offset = found->offset;
      vi.range = found->range;
      VkBufferView view = VK_NULL_HANDLE;
      check(vkCreateBufferView(ctx_.device(), &vi, nullptr, &view), (where(rb.binding) + ": vkCreateBufferView").c_str());
      views_.push_back(view);
      texel_views.push_back(view);
      wr.pTexelBufferView = &texel_views.back();
    } else if (is_image_type(rb.type) || rb.type == VK_DESCRIPTOR_TYPE_SAMPLER) {
      if (rb.type != VK_DESCRIPTOR_TYPE_SAMPLER && (!found->image || !*found->image))
        throw std::invalid_argument(where(rb.binding) + ": expects an image");
      if ((rb.type == VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER || rb.type == VK_DESCRIPTOR_TYPE_SAMPLER) && !found->sampler)
        throw std::invalid_argument(where(rb.binding) + ": expects a sampler");
      images.push_back({found->sampler, found->image ? found->image->view() : VK_NULL_HANDLE, found->image_layout});
      wr.pImageInfo = &images.back();
    } else {
      throw std::invalid_argument(where(rb.binding) + ": descriptor type not supported by Recorder");
    }
    writes.push_back(wr);
  }
  vkUpdateDescriptorSets(ctx_.device(), static_cast<std::uint32_t>(writes.size()), writes.data(), 0, nullptr);
  return ds;
}

void Recorder::dispatch(const ComputePipeline& p, const std::vector<Bind>& binds, const void* push, std::uint32_t push_bytes,
                        std::uint32_t gx, std::uint32_t gy, std::uint32_t gz) {
  const auto& lim = ctx_.device_info().limits;
  if (gx > lim.maxComputeWorkGroupCount[0] || gy > lim.maxComputeWorkGroupCount[1] || gz > lim.maxComputeWorkGroupCount[2])
    throw std::invalid_argument("vulkan: dispatch of '" + p.name() + "' with " + std::to_string(gx) + "x" + std::to_string(gy) + "x" +
                                std::to_string(gz) + " workgroups exceeds the device's maxComputeWorkGroupCount");
  const PipelineLayout& layout = p.layout();
  if (push_bytes != layout.push_constant_size())
    throw std::invalid_argument("vulkan: dispatch of '" + p.name() + "' with " + std::to_string(push_bytes) +
                                " bytes of push constants; the shader declares " + std::to_string(layout.push_constant_size()));
  vkCmdBindPipeline(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, p.handle());
  for (std::uint32_t s = 0; s < layout.set_count(); ++s) {
    VkDescriptorSet ds = descriptor_set(layout, s, binds);
    vkCmdBindDescriptorSets(cmd_, VK_PIPELINE_BIND_POINT_COMPUTE, layout.handle(), s, 1, &ds, 0, nullptr);
  }
  if (push_bytes > 0) vkCmdPushConstants(cmd_, layout.handle(), layout.push_constant_stages(), 0, push_bytes, push);
  if (gx > 0 && gy > 0 && gz > 0) vkCmdDispatch(cmd_, gx, gy, gz);
}

void Recorder::barrier() {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT | VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cmd_, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT | VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                       &mb, 0, nullptr, 0, nullptr);
}

void Recorder::copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes, VkDeviceSize src_offset, VkDeviceSize dst_offset) {
  if (src_offset + bytes > src.size() || dst_offset + bytes > dst.size())
    throw std::out_of_range("vulkan: copy of " + std::to_string(bytes) + " bytes from '" + src.name() + "' to '" + dst.name() +
                            "' out of range");
  VkBufferCopy c{src_offset, dst_offset, bytes};
  vkCmdCopyBuffer(cmd_, src.handle(), dst.handle(), 1, &c);
}

void Recorder::fill(const Buffer& dst, std::uint32_t value) { vkCmdFillBuffer(cmd_, dst.handle(), 0, VK_WHOLE_SIZE, value); }

void Recorder::begin_timer(const std::string& label) {
  if (timer_open_) throw std::logic_error("vulkan: timer '" + label + "' begun while another is open");
  timer_open_ = true;
  timer_labels_.push_back(label);
  if (!ctx_.query_pool_) return;
  if (ctx_.queries_used_ + 3 > ctx_.query_capacity_) throw std::length_error("vulkan: too many timers in one submission");
  vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, ctx_.query_pool_, ctx_.queries_used_++);
}

void Recorder::end_timer() {
  if (!timer_open_) throw std::logic_error("vulkan: end_timer without begin_timer");
  timer_open_ = false;
  if (ctx_.query_pool_) vkCmdWriteTimestamp(cmd_, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, ctx_.query_pool_, ctx_.queries_used_++);
}

Owned<VkRenderPass> create_render_pass(Context& ctx, const RenderPassDesc& d) {
  const bool has_depth = d.depth != VK_FORMAT_UNDEFINED;
  const auto colors = static_cast<std::uint32_t>(d.colors.size());
  std::vector<VkAttachmentDescription> att(colors + (has_depth ? 1u : 0u));
  std::vector<VkAttachmentReference> color_refs(colors);
  for (std::uint32_t a = 0; a < att.size(); ++a) {
    const bool depth = a == colors;
    att[a].format = depth ? d.depth : d.colors[a];
    att[a].samples = VK_SAMPLE_COUNT_1_BIT;
    att[a].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    att[a].storeOp = !depth || d.copy_depth ? VK_ATTACHMENT_STORE_OP_STORE : VK_ATTACHMENT_STORE_OP_DONT_CARE;
    att[a].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
    att[a].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    att[a].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    att[a].finalLayout = !depth || d.copy_depth ? VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL : VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    if (!depth) color_refs[a] = {a, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  }
  const VkAttachmentReference depth_ref{colors, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub{};
  sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  sub.colorAttachmentCount = colors;
  sub.pColorAttachments = color_refs.data();
  sub.pDepthStencilAttachment = has_depth ? &depth_ref : nullptr;
  // Flags, or none, as the attachment kinds present ask.
  const auto when = [](bool present, VkFlags flags) -> VkFlags { return present ? flags : 0u; };
  const VkFlags tests = VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  const VkFlags depth_rw = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  const VkFlags color_rw = VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  // Before: the previous use's copies out of the same attachments (write after read) and its depth
  // writes. After: the copies read what the subpass wrote.
  std::array<VkSubpassDependency, 2> deps{};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT | when(has_depth, VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT);
  deps[0].dstStageMask = when(colors > 0, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT) | when(has_depth, tests);
  deps[0].srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT | when(has_depth, VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
  deps[0].dstAccessMask = when(colors > 0, color_rw) | when(has_depth, depth_rw);
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = when(colors > 0, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT) | when(d.copy_depth, tests);
  deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[1].srcAccessMask = when(colors > 0, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT) | when(d.copy_depth, VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
  deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  VkRenderPassCreateInfo rp{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  rp.attachmentCount = static_cast<std::uint32_t>(att.size());
  rp.pAttachments = att.data();
  rp.subpassCount = 1;
  rp.pSubpasses = &sub;
  rp.dependencyCount = static_cast<std::uint32_t>(deps.size());
  rp.pDependencies = deps.data();
  VkDevice dev = ctx.device();
  VkRenderPass pass = VK_NULL_HANDLE;
  const std::string what = "vkCreateRenderPass (" + d.name + ")";
  check(vkCreateRenderPass(dev, &rp, nullptr, &pass), what.c_str());
  ctx.set_name(VK_OBJECT_TYPE_RENDER_PASS, reinterpret_cast<std::uint64_t>(pass), d.name);
  return Owned<VkRenderPass>(pass, [dev](VkRenderPass x) { vkDestroyRenderPass(dev, x, nullptr); });
}

Owned<VkFramebuffer> create_framebuffer(Context& ctx, VkRenderPass pass, const std::vector<VkImageView>& views, std::uint32_t width,
                                        std::uint32_t height, const std::string& name) {
  VkFramebufferCreateInfo fi{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
  fi.renderPass = pass;
  fi.attachmentCount = static_cast<std::uint32_t>(views.size());
  fi.pAttachments = views.data();
  fi.width = width;
  fi.height = height;
  fi.layers = 1;
  VkDevice dev = ctx.device();
  VkFramebuffer fb = VK_NULL_HANDLE;
  const std::string what = "vkCreateFramebuffer (" + name + ")";
  check(vkCreateFramebuffer(dev, &fi, nullptr, &fb), what.c_str());
  return Owned<VkFramebuffer>(fb, [dev](VkFramebuffer x) { vkDestroyFramebuffer(dev, x, nullptr); });
}

Owned<VkPipeline> create_graphics_pipeline(Context& ctx, const GraphicsPipelineDesc& d) {
  std::vector<VkPipelineShaderStageCreateInfo> stages;
  VkPipelineShaderStageCreateInfo vs{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  vs.stage = VK_SHADER_STAGE_VERTEX_BIT;
  vs.module = d.vertex;
  vs.pName = d.vertex_entry.c_str();
  stages.push_back(vs);
  if (d.fragment != VK_NULL_HANDLE) {
    VkPipelineShaderStageCreateInfo fs{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    fs.stage = VK_SHADER_STAGE_FRAGMENT_BIT;
    fs.module = d.fragment;
    fs.pName = d.fragment_entry.c_str();
    fs.pSpecializationInfo = d.fragment_spec;
    stages.push_back(fs);
  }
  VkPipelineVertexInputStateCreateInfo vi{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineInputAssemblyStateCreateInfo ia{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo vp{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  vp.viewportCount = 1;
  vp.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo rs{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  rs.polygonMode = VK_POLYGON_MODE_FILL;
  rs.cullMode = d.cull;
  rs.frontFace = d.front_face;
  rs.lineWidth = 1.0f;
  VkPipelineMultisampleStateCreateInfo ms{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineColorBlendStateCreateInfo cb{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  cb.attachmentCount = static_cast<std::uint32_t>(d.blend.size());
  cb.pAttachments = d.blend.data();
  const std::array<VkDynamicState, 2> dyn = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dy{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dy.dynamicStateCount = static_cast<std::uint32_t>(dyn.size());
  dy.pDynamicStates = dyn.data();
  VkGraphicsPipelineCreateInfo gi{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  gi.stageCount = static_cast<std::uint32_t>(stages.size());
  gi.pStages = stages.data();
  gi.pVertexInputState = &vi;
  gi.pInputAssemblyState = &ia;
  gi.pViewportState = &vp;
  gi.pRasterizationState = &rs;
  gi.pMultisampleState = &ms;
  gi.pDepthStencilState = d.depth;
  gi.pColorBlendState = &cb;
  gi.pDynamicState = &dy;
  gi.layout = d.layout;
  gi.renderPass = d.render_pass;
  gi.subpass = 0;
  VkDevice dev = ctx.device();
  VkPipeline pipeline = VK_NULL_HANDLE;
  const std::string what = "vkCreateGraphicsPipelines (" + d.name + ")";
  check(vkCreateGraphicsPipelines(dev, VK_NULL_HANDLE, 1, &gi, nullptr, &pipeline), what.c_str());
  ctx.set_name(VK_OBJECT_TYPE_PIPELINE, reinterpret_cast<std::uint64_t>(pipeline), d.name);
  return Owned<VkPipeline>(pipeline, [dev](VkPipeline x) { vkDestroyPipeline(dev, x, nullptr); });
}

VkPipelineColorBlendAttachmentState write_all_channels() {
  VkPipelineColorBlendAttachmentState b{};
  b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
  return b;
}

}  // namespace softgi::backends::vulkan
