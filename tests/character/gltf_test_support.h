// Test support for the glTF importer and animation: the assets, GLB editing in memory, and
// (from skinserve/reference/gltf_reference.h) an independent float64 reading and evaluation
// of a skinned glTF (own JSON/accessor reading, own slerp/Hermite, own hierarchy, own
// skinning) that shares no code with core/character or core/animation.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "skinserve/reference/gltf_reference.h"

namespace skinserve::testing {

// The test characters live in the repository (tests/assets/gltf, credited in its
// SOURCES.md); CMake passes the folder in. A missing one is a broken checkout: the test
// fails saying so, it never skips.
std::string AssetPath(const std::string& file);
bool AssetExists(const std::string& file);
#define REQUIRE_ASSET(file)                                                           \
  ASSERT_TRUE(::skinserve::testing::AssetExists(file))                                \
      << "test asset " << ::skinserve::testing::AssetPath(file)                       \
      << " is missing: it is part of the repository (tests/assets/gltf); restore it " \
         "with git checkout"

std::vector<uint8_t> ReadBytes(const std::string& path);

// The independent float64 model of a skinned glTF (skinserve/reference/gltf_reference.h,
// shared with skinserve-load --animate FILE) under the tests' names.
using gltf_reference::Compose;
using gltf_reference::ElementOffset;
using gltf_reference::Glb;
using gltf_reference::Mat4;
using gltf_reference::ParseGlb;
using gltf_reference::ReadAccessor;
using gltf_reference::ReadReference;
using gltf_reference::RefChannel;
using gltf_reference::RefCharacter;
using gltf_reference::RefClip;
using gltf_reference::RefFrame;
using gltf_reference::RefNode;
using gltf_reference::RefPalette;
using gltf_reference::RefPrimitive;
using gltf_reference::RefSample;
using gltf_reference::RefSkin;

// A GLB put back together after editing.
std::vector<uint8_t> BuildGlb(const Glb& glb);
// Appends `bytes` to the BIN chunk as a new bufferView (4-byte aligned); returns its index.
int AppendBufferView(Glb& glb, const std::vector<uint8_t>& bytes);
// Appends an accessor over a new bufferView holding `bytes`; returns its index.
int AppendAccessor(Glb& glb, const std::vector<uint8_t>& bytes, int component_type,
                   const std::string& type, std::size_t count, bool normalized = false);
// Quaternions q and -q are one rotation: the distance between two as rotations.
double QuatDistance(const double a[4], const double b[4]);

}  // namespace skinserve::testing
