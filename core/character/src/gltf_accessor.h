// AccessorReader: one glTF accessor, validated against its buffer view and buffer before a
// single byte is read, so a malformed file gives an error naming the object and never an
// out-of-bounds read.
#pragma once

#include <tiny_gltf.h>

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::gltf {

// "VEC3", "MAT4", ... for messages.
const char* AccessorTypeName(int type);
// "FLOAT", "UNSIGNED_BYTE", ... for messages.
const char* ComponentTypeName(int component_type);

class AccessorReader {
 public:
  // Checks accessor `index` for use as `what` (the referring object, e.g.
  // "meshes[0].primitives[0].attributes.JOINTS_0"): the index is in range, its type is
  // `type`, its componentType one of `component_types`, its bufferView and buffer exist, and
  // every element lies inside the bufferView, which lies inside its buffer. A sparse
  // accessor's indices (strictly increasing, below count) and values are checked the same
  // way; its reads then give the substituted values.
  static Result<AccessorReader> Open(const tinygltf::Model& model, int index,
                                     const std::string& what, int type,
                                     std::initializer_list<int> component_types);

  int index() const { return index_; }
  std::size_t count() const { return count_; }
  int components() const { return components_; }
  int component_type() const { return component_type_; }
  // The accessor's `normalized` flag (integer component types only).
  bool normalized() const { return normalized_; }

  // Component `c` of element `e` as the stored integer (integer component types only).
  uint32_t Uint(std::size_t e, int c) const;
  // Component `c` of element `e` as a float: floats as stored; integer types as normalized
  // values per the spec's conversion (unsigned c / max; signed max(c / max, -1)).
  float Normalized(std::size_t e, int c) const;
  // Component `c` of element `e` as the accessor means it: Normalized() when the accessor
  // is a float or flagged `normalized`, else the stored integer as a float
  // (KHR_mesh_quantization's unnormalized positions).
  float Value(std::size_t e, int c) const;

 private:
  // Where component `c` of element `e` is stored; nullptr for an all-zero element.
  const uint8_t* Address(std::size_t e, int c) const;

  int index_ = -1;
  const uint8_t* data_ = nullptr;  // nullptr: the accessor has no bufferView, all zeros
  std::size_t count_ = 0;
  std::size_t stride_ = 0;
  std::size_t component_size_ = 0;
  int components_ = 0;
  int component_type_ = 0;
  bool normalized_ = false;
  // Sparse substitution: element sparse_indices_[k] reads sparse_values_ + k * element size.
  std::vector<uint32_t> sparse_indices_;
  const uint8_t* sparse_values_ = nullptr;
  std::size_t element_size_ = 0;
};

}  // namespace skinserve::gltf
