#include "gltf_accessor.h"

#include <fmt/format.h>
#include <algorithm>
#include <cstring>

namespace skinserve::gltf {
namespace {

int ComponentCount(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

std::size_t ComponentSize(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

std::string AllowedNames(std::initializer_list<int> component_types) {
  std::string names;
  for (int t : component_types) {
    if (!names.empty()) names += ", ";
    names += ComponentTypeName(t);
  }
  return names;
}

}  // namespace

const char* AccessorTypeName(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "unknown";
  }
}

const char* ComponentTypeName(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT:
      return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "FLOAT";
    default:
      return "unknown";
  }
}

Result<AccessorReader> AccessorReader::Open(const tinygltf::Model& model, int index,
                                            const std::string& what, int type,
                                            std::initializer_list<int> component_types) {
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) {
    return InvalidArgument(fmt::format("{}: accessor {} does not exist (the file has {})", what,
                                       index, model.accessors.size()));
  }
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
  if (a.type != type) {
    return InvalidArgument(fmt::format("{}: accessor {} has type {}; expected {}", what, index,
                                       AccessorTypeName(a.type), AccessorTypeName(type)));
  }
  if (std::find(component_types.begin(), component_types.end(), a.componentType) ==
      component_types.end()) {
    return InvalidArgument(fmt::format(
        "{}: accessor {} has componentType {} ({}); allowed: {}", what, index, a.componentType,
        ComponentTypeName(a.componentType), AllowedNames(component_types)));
  }
  // Sparse substitution is rare in skinned characters; refusing it is better than reading
  // the base values and skinning the wrong shape.
  if (a.sparse.isSparse) {
    return InvalidArgument(
        fmt::format("{}: accessor {} is sparse; sparse accessors are not supported", what, index));
  }
  if (a.count == 0) {
    return InvalidArgument(
        fmt::format("{}: accessor {} has count 0; the minimum is 1", what, index));
  }

  AccessorReader r;
  r.index_ = index;
  r.count_ = a.count;
  r.components_ = ComponentCount(type);
  r.component_type_ = a.componentType;
  r.component_size_ = ComponentSize(a.componentType);
  const std::size_t element_size = r.component_size_ * static_cast<std::size_t>(r.components_);
  if (a.bufferView < 0) return r;  // the spec's all-zero accessor: data_ stays null

  if (static_cast<std::size_t>(a.bufferView) >= model.bufferViews.size()) {
    return InvalidArgument(
        fmt::format("{}: accessor {} refers to bufferView {}, which does not "
                    "exist (the file has {})",
                    what, index, a.bufferView, model.bufferViews.size()));
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(a.bufferView)];
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
    return InvalidArgument(
        fmt::format("{}: bufferView {} refers to buffer {}, which does not "
                    "exist (the file has {})",
                    what, a.bufferView, view.buffer, model.buffers.size()));
  }
  const std::vector<unsigned char>& buffer =
      model.buffers[static_cast<std::size_t>(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
    return InvalidArgument(fmt::format(
        "{}: bufferView {} (byteOffset {}, byteLength {}) reaches past buffer {} of {} bytes", what,
        a.bufferView, view.byteOffset, view.byteLength, view.buffer, buffer.size()));
  }
  r.stride_ = view.byteStride == 0 ? element_size : view.byteStride;
  if (r.stride_ < element_size) {
    return InvalidArgument(fmt::format(
        "{}: bufferView {} has byteStride {}, smaller than accessor {}'s element of {} bytes", what,
        a.bufferView, view.byteStride, index, element_size));
  }
  // (count - 1) * stride <= room, written as a division so that no product can overflow.
  const bool fits = a.byteOffset <= view.byteLength &&
                    element_size <= view.byteLength - a.byteOffset &&
                    a.count - 1 <= (view.byteLength - a.byteOffset - element_size) / r.stride_;
  if (!fits) {
    return InvalidArgument(fmt::format(
        "{}: accessor {} reads past bufferView {}: byteOffset {} + stride {} * (count {} - 1) + "
        "element size {} exceeds byteLength {}",
        what, index, a.bufferView, a.byteOffset, r.stride_, a.count, element_size,
        view.byteLength));
  }
  r.data_ = buffer.data() + view.byteOffset + a.byteOffset;
  return r;
}

const uint8_t* AccessorReader::Address(std::size_t e, int c) const {
  return data_ + e * stride_ + static_cast<std::size_t>(c) * component_size_;
}

uint32_t AccessorReader::Uint(std::size_t e, int c) const {
  if (data_ == nullptr) return 0;
  const uint8_t* p = Address(e, c);
  switch (component_type_) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    default:
      return 0;  // Open() admits only the types its caller reads
  }
}

float AccessorReader::Normalized(std::size_t e, int c) const {
  if (data_ == nullptr) return 0.0f;
  const uint8_t* p = Address(e, c);
  switch (component_type_) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return static_cast<float>(*p) / 255.0f;
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, sizeof v);
      return std::max(static_cast<float>(v) / 127.0f, -1.0f);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, sizeof v);
      return static_cast<float>(v) / 65535.0f;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, sizeof v);
      return std::max(static_cast<float>(v) / 32767.0f, -1.0f);
    }
    default:
      return 0.0f;  // Open() admits only the types its caller reads
  }
}

}  // namespace skinserve::gltf
