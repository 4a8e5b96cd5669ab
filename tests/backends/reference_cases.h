// The mesh shapes every backend is checked on against the float64 reference, and what
// the checks share: a case's mesh (seeded by its shape), its test name, and one frame
// skinned into NaN-filled outputs and compared with the reference. Used by the backend
// conformance and dual-quaternion tests (tests/backends) and the OpenCL tests
// (tests/opencl), each with its own list of shapes.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/skinning_method.h"

namespace skinserve::testing {

struct MeshCase {
  uint32_t vertices;
  uint32_t influences;
  uint32_t joints;
  bool normals;
  bool tangents = false;  // with normals only
};

// Every combination of the vertex counts (each at most TargetCheckMaxVertices()),
// 1..max_influences, the joint counts and without normals, with normals, and with normals
// and tangents.
std::vector<MeshCase> MeshCases(std::initializer_list<uint32_t> vertices,
                                std::initializer_list<uint32_t> joints,
                                uint32_t max_influences = kMaxInfluences);

// The vertex count of the suites' large, odd-sized cases (several threads' and vector
// chunks' worth): 100003, or SKINSERVE_TEST_LARGE_VERTICES where set (the arm64 suite under
// qemu, where a 100k-vertex frame takes seconds per backend). A value that is not an odd
// number of at least 4097 vertices fails the suite rather than shrinking what it checks.
uint32_t LargeCaseVertices();

// The longest frame the per-SIMD-target checks and MeshCases skin: unlimited, or
// SKINSERVE_TEST_TARGET_MAX_VERTICES where set (the arm64 suite under qemu sets 257: every
// tail and the first chunk boundary; there each target costs minutes, and the x86 suite
// checks the longer frames of the same loops). A value below 33 ends the run.
uint32_t TargetCheckMaxVertices();

// The case's synthetic mesh; its seed follows from its shape, so a failure reproduces.
std::shared_ptr<const Mesh> CaseMesh(const MeshCase& c);
uint64_t CaseSeed(const MeshCase& c);

// "<backend>_V<vertices>_B<influences>_J<joints>[_normals][_tangents]", '-' as '_'.
using BackendCase = std::tuple<std::string, MeshCase>;
std::string CaseName(const ::testing::TestParamInfo<BackendCase>& info);

// Skins `palette` with `backend` into outputs pre-filled with NaN (an element the backend
// skips shows up) and expects them within CompareWithReference's tolerance, naming the
// backend, the case and `what` otherwise. A backend that does not skin tangents
// (BackendInfo::tangents) must refuse a case with tangents with FAILED_PRECONDITION.
void ExpectFrameMatchesReference(Backend& backend, const PreparedMesh& prepared, const Mesh& mesh,
                                 std::span<const float> palette, const MeshCase& c,
                                 SkinningMethod method, const std::string& what);

}  // namespace skinserve::testing
