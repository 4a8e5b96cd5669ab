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

namespace {

// The bytes of bufferView `view_index` from `byte_offset` that hold `count` elements of
// `element_size` bytes, `stride` apart, after checking that the view lies inside its
// buffer and the elements inside the view. `label` names the reader in messages
// ("accessor 3", "accessor 3 sparse.indices").
Result<const uint8_t*> ViewBytes(const tinygltf::Model& model, int view_index,
                                 std::size_t byte_offset, std::size_t element_size,
                                 std::size_t stride, std::size_t count, const std::string& what,
                                 const std::string& label) {
  if (view_index < 0 || static_cast<std::size_t>(view_index) >= model.bufferViews.size()) {
    return InvalidArgument(
        fmt::format("{}: {} refers to bufferView {}, which does not exist (the file has {})", what,
                    label, view_index, model.bufferViews.size()));
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(view_index)];
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
    return InvalidArgument(
        fmt::format("{}: bufferView {} refers to buffer {}, which does not "
                    "exist (the file has {})",
                    what, view_index, view.buffer, model.buffers.size()));
  }
  const std::vector<unsigned char>& buffer =
      model.buffers[static_cast<std::size_t>(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
    return InvalidArgument(fmt::format(
        "{}: bufferView {} (byteOffset {}, byteLength {}) reaches past buffer {} of {} bytes", what,
        view_index, view.byteOffset, view.byteLength, view.buffer, buffer.size()));
  }
  // (count - 1) * stride <= room, written as a division so that no product can overflow.
  const bool fits = byte_offset <= view.byteLength &&
                    element_size <= view.byteLength - byte_offset &&
                    count - 1 <= (view.byteLength - byte_offset - element_size) / stride;
  if (!fits) {
    return InvalidArgument(fmt::format(
        "{}: {} reads past bufferView {}: byteOffset {} + stride {} * (count {} - 1) + "
        "element size {} exceeds byteLength {}",
        what, label, view_index, byte_offset, stride, count, element_size, view.byteLength));
  }
  return buffer.data() + view.byteOffset + byte_offset;
}

uint32_t ReadIndex(const uint8_t* p, int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
  }
}

// The accessor exists, has `type`, one of `component_types` and at least one element.
Status CheckAccessor(const tinygltf::Model& model, int index, const std::string& what, int type,
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
  if (a.count == 0) {
    return InvalidArgument(
        fmt::format("{}: accessor {} has count 0; the minimum is 1", what, index));
  }
  return Status::Ok();
}

// An accessor's sparse substitution: element indices[k] reads values + k * element size.
struct SparseSubstitution {
  std::vector<uint32_t> indices;
  const uint8_t* values = nullptr;
};

// Sparse substitution (glTF 2.0 3.6.2.3): `count` strictly increasing indices, each
// below the accessor's count, and as many tightly packed values of the accessor's type.
Result<SparseSubstitution> ReadSparse(const tinygltf::Model& model, const tinygltf::Accessor& a,
                                      int index, std::size_t element_size, const std::string& what,
                                      const std::string& label) {
  const auto& sparse = a.sparse;
  SparseSubstitution out;
  if (sparse.count < 1 || static_cast<std::size_t>(sparse.count) > a.count) {
    return InvalidArgument(fmt::format("{}: accessor {} sparse.count is {}; must be 1..{}", what,
                                       index, sparse.count, a.count));
  }
  const int index_type = sparse.indices.componentType;
  if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    return InvalidArgument(fmt::format(
        "{}: accessor {} sparse.indices.componentType is {} ({}); allowed: UNSIGNED_BYTE, "
        "UNSIGNED_SHORT, UNSIGNED_INT",
        what, index, index_type, ComponentTypeName(index_type)));
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
    return InvalidArgument(
        fmt::format("{}: accessor {} sparse byteOffset is negative", what, index));
  }
  const auto n = static_cast<std::size_t>(sparse.count);
  const std::size_t index_size = ComponentSize(index_type);
  auto indices = ViewBytes(model, sparse.indices.bufferView,
                           static_cast<std::size_t>(sparse.indices.byteOffset), index_size,
                           index_size, n, what, label + " sparse.indices");
  if (!indices.ok()) return indices.status();
  auto values =
      ViewBytes(model, sparse.values.bufferView, static_cast<std::size_t>(sparse.values.byteOffset),
                element_size, element_size, n, what, label + " sparse.values");
  if (!values.ok()) return values.status();
  out.indices.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const uint32_t e = ReadIndex(*indices + k * index_size, index_type);
    if (e >= a.count) {
      return InvalidArgument(
          fmt::format("{}: accessor {} sparse.indices[{}] = {} is not below its count {}", what,
                      index, k, e, a.count));
    }
    if (k > 0 && e <= out.indices[k - 1]) {
      return InvalidArgument(fmt::format(
          "{}: accessor {} sparse.indices[{}] = {} does not increase (the one before is {})", what,
          index, k, e, out.indices[k - 1]));
    }
    out.indices[k] = e;
  }
  out.values = *values;
  return out;
}

}  // namespace

Result<AccessorReader> AccessorReader::Open(const tinygltf::Model& model, int index,
                                            const std::string& what, int type,
                                            std::initializer_list<int> component_types) {
  if (Status s = CheckAccessor(model, index, what, type, component_types); !s.ok()) return s;
  const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
  AccessorReader r;
  r.index_ = index;
  r.count_ = a.count;
  r.components_ = ComponentCount(type);
  r.component_type_ = a.componentType;
  r.component_size_ = ComponentSize(a.componentType);
  r.normalized_ = a.normalized && a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT;
  r.element_size_ = r.component_size_ * static_cast<std::size_t>(r.components_);
  const std::string label = fmt::format("accessor {}", index);

  if (a.bufferView >= 0) {  // else the spec's all-zero base: data_ stays null
    const std::size_t view_stride =
        static_cast<std::size_t>(a.bufferView) < model.bufferViews.size()
            ? model.bufferViews[static_cast<std::size_t>(a.bufferView)].byteStride
            : 0;
    r.stride_ = view_stride == 0 ? r.element_size_ : view_stride;
    if (r.stride_ < r.element_size_) {
      return InvalidArgument(fmt::format(
          "{}: bufferView {} has byteStride {}, smaller than accessor {}'s element of {} bytes",
          what, a.bufferView, view_stride, index, r.element_size_));
    }
    auto data = ViewBytes(model, a.bufferView, a.byteOffset, r.element_size_, r.stride_, a.count,
                          what, label);
    if (!data.ok()) return data.status();
    r.data_ = *data;
  }

  if (!a.sparse.isSparse) return r;
  auto sparse = ReadSparse(model, a, index, r.element_size_, what, label);
  if (!sparse.ok()) return sparse.status();
  r.sparse_indices_ = std::move(sparse->indices);
  r.sparse_values_ = sparse->values;
  return r;
}

const uint8_t* AccessorReader::Address(std::size_t e, int c) const {
  const std::size_t offset = static_cast<std::size_t>(c) * component_size_;
  if (!sparse_indices_.empty()) {
    const auto it = std::lower_bound(sparse_indices_.begin(), sparse_indices_.end(), e);
    if (it != sparse_indices_.end() && *it == e) {
      return sparse_values_ +
             static_cast<std::size_t>(it - sparse_indices_.begin()) * element_size_ + offset;
    }
  }
  if (data_ == nullptr) return nullptr;
  return data_ + e * stride_ + offset;
}

uint32_t AccessorReader::Uint(std::size_t e, int c) const {
  const uint8_t* p = Address(e, c);
  if (p == nullptr) return 0;
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
  const uint8_t* p = Address(e, c);
  if (p == nullptr) return 0.0f;
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

float AccessorReader::Value(std::size_t e, int c) const {
  if (component_type_ == TINYGLTF_COMPONENT_TYPE_FLOAT || normalized_) return Normalized(e, c);
  const uint8_t* p = Address(e, c);
  if (p == nullptr) return 0.0f;
  switch (component_type_) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    default:
      return static_cast<float>(Uint(e, c));
  }
}

}  // namespace skinserve::gltf
