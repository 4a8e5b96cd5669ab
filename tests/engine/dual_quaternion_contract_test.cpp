// Dual-quaternion skinning's contract in the engine: palettes that are not rigid are
// refused naming the joint and what is wrong (scale, shear, reflection, non-finite), a
// backend that lacks the method (only passthrough now) is refused naming the backends
// that have it, and a good frame goes through to the float64 reference on the scalar, SSE
// and Highway loops.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "cpu_backend_ids.h"
#include "skinserve/engine/engine.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

class DualQuaternionContractTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto engine = Engine::Create({.enabled_backends = {"serial", kDualQuaternionOpenMpTestBackend,
                                                       "simd-openmp", "passthrough"}});
    ASSERT_TRUE(engine.ok()) << engine.status().ToString();
    engine_ = std::move(engine).value();
    arrays_ = MakeSyntheticMesh(
        {.vertex_count = 101, .influences = 3, .joint_count = 5, .normals = true, .seed = 3});
    auto info = engine_->AddMesh(arrays_);
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    info_ = *info;
    positions_.assign(3 * 101, 0.0f);
    normals_.assign(3 * 101, 0.0f);
  }

  Status Skin(const std::string& backend, std::vector<float> palette) {
    return engine_->SkinBlocking({.mesh_id = info_.id,
                                  .backend = backend,
                                  .palette = palette,
                                  .positions = positions_,
                                  .normals = normals_,
                                  .method = SkinningMethod::kDualQuaternion});
  }

  // A rigid palette with joint 3's matrix changed by `edit`.
  Status SkinWithJoint3(const std::function<void(float* m)>& edit) {
    std::vector<float> palette = MakeRigidPalette(5, 9, 0);
    edit(&palette[kFloatsPerJoint * 3]);
    return Skin("serial", palette);
  }

  std::unique_ptr<Engine> engine_;
  MeshArrays arrays_;
  MeshInfo info_;
  std::vector<float> positions_, normals_;
};

void ExpectRefused(const Status& s, const std::string& part) {
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find(part), std::string::npos) << s.message();
}

TEST_F(DualQuaternionContractTest, RigidFramesMatchTheReference) {
  for (const std::string backend : {"serial", kDualQuaternionOpenMpTestBackend, "simd-openmp"}) {
    const std::vector<float> palette = MakeRigidPalette(5, 9, 1);
    ASSERT_TRUE(Skin(backend, palette).ok()) << backend;
    const auto mesh = Mesh::Create(arrays_).value();
    const Deviation d =
        CompareWithReference(*mesh, palette, positions_, normals_, SkinningMethod::kDualQuaternion);
    EXPECT_TRUE(d.within_tolerance())
        << backend << " " << d.max_position_error << " " << d.max_normal_error;
  }
}

TEST_F(DualQuaternionContractTest, ScaleIsRefusedNamingTheJoint) {
  const Status s = SkinWithJoint3([](float* m) {
    for (int r = 0; r < 3; ++r) m[4 * r] *= 1.01f;  // column 0 stretched by 1%
  });
  ExpectRefused(s, "palette[joint 3] is not rigid: column 0 has length 1.01");
  ExpectRefused(s, "(scale)");
  ExpectRefused(s, "within 0.001");
}

TEST_F(DualQuaternionContractTest, UniformScaleIsRefusedToo) {
  ExpectRefused(SkinWithJoint3([](float* m) {
                  for (int e : {0, 1, 2, 4, 5, 6, 8, 9, 10}) m[e] *= 0.5f;
                }),
                "palette[joint 3] is not rigid: column 0 has length 0.5");
}

TEST_F(DualQuaternionContractTest, ShearIsRefusedNamingTheJoint) {
  // Column 1 += 0.05 * column 0: lengths change by only 0.1%, the columns' dot is 0.05.
  const Status s = SkinWithJoint3([](float* m) {
    for (int r = 0; r < 3; ++r) m[4 * r + 1] += 0.05f * m[4 * r];
  });
  ExpectRefused(s, "palette[joint 3] is not rigid");
  ExpectRefused(s, "(shear)");
}

TEST_F(DualQuaternionContractTest, ReflectionIsRefusedNamingTheJoint) {
  const Status s = SkinWithJoint3([](float* m) {
    for (int r = 0; r < 3; ++r) m[4 * r + 2] = -m[4 * r + 2];  // mirror column 2
  });
  ExpectRefused(s, "palette[joint 3] is not rigid: det R = -1");
  ExpectRefused(s, "(a reflection)");
}

TEST_F(DualQuaternionContractTest, NonFiniteIsRefusedNamingTheJoint) {
  ExpectRefused(SkinWithJoint3([](float* m) { m[6] = std::numeric_limits<float>::infinity(); }),
                "palette[joint 3][row 1, col 2] = inf is not finite");
  ExpectRefused(SkinWithJoint3([](float* m) { m[3] = std::nanf(""); }),
                "palette[joint 3][row 0, col 3] = nan is not finite");
}

TEST_F(DualQuaternionContractTest, SmallRoundingIsAccepted) {
  // Float32 matrices composed along a joint chain are rigid only to rounding.
  EXPECT_TRUE(SkinWithJoint3([](float* m) {
                for (int r = 0; r < 3; ++r) m[4 * r] *= 1.0001f;
              }).ok());
}

TEST_F(DualQuaternionContractTest, LinearStillTakesScaledPalettes) {
  const std::vector<float> scaled_palette = MakeSyntheticPalette(5, 9, 0);
  EXPECT_TRUE(engine_
                  ->SkinBlocking({.mesh_id = info_.id,
                                  .backend = "serial",
                                  .palette = scaled_palette,
                                  .positions = positions_,
                                  .normals = normals_,
                                  .method = SkinningMethod::kLinear})
                  .ok());
}

TEST_F(DualQuaternionContractTest, ABackendWithoutTheMethodIsRefusedNamingThoseWithIt) {
  const Status s = Skin("passthrough", MakeRigidPalette(5, 9, 0));
  ExpectRefused(s, "backend 'passthrough' does not implement method dual-quaternion");
  ExpectRefused(s, "(it implements linear)");
  ExpectRefused(s, std::string("backends here that do: serial, ") +
                       kDualQuaternionOpenMpTestBackend + ", simd-openmp");
}

TEST_F(DualQuaternionContractTest, EngineListsEachBackendsMethods) {
  for (const BackendInfo& info : engine_->Backends()) {
    EXPECT_TRUE(info.Supports(SkinningMethod::kLinear)) << info.id;
    EXPECT_EQ(info.Supports(SkinningMethod::kDualQuaternion), info.id != "passthrough") << info.id;
  }
}

TEST(SkinningMethodTest, NamesRoundTrip) {
  for (SkinningMethod m : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    EXPECT_EQ(ParseMethod(MethodName(m)), m);
  }
  EXPECT_EQ(MethodName(SkinningMethod::kDualQuaternion), "dual-quaternion");
  EXPECT_FALSE(ParseMethod("dqs").has_value());
}

}  // namespace
}  // namespace skinserve
