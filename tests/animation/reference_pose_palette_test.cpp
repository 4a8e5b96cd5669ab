// core/reference's float64 pose (skinserve/reference/pose_reference.h, what skinserve-load
// --animate checks the server's answers against) agrees with this folder's own float64
// evaluation of the same channels (pose_reference.h: tests/character's glTF formulas,
// slerp, Hermite and hierarchy), written apart from it: on the synthetic 77-joint clip and
// the test characters' clips, on keys, between keys, before and after the clip.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "pose_reference.h"
#include "skinserve/reference/pose_reference.h"

namespace skinserve::testing {
namespace {

void ExpectSamePalettes(const PoseCase& c) {
  for (const double t : SampleTimes(c)) {
    const std::vector<double> got = ReferencePosePalette(c.skeleton, c.raw, t);
    const std::vector<double> model_then_palette = RefModel(c, t);
    ASSERT_EQ(got.size(), 12 * c.skeleton.palette_size()) << c.label;
    const std::size_t palette_at = model_then_palette.size() - got.size();
    for (std::size_t i = 0; i < got.size(); ++i) {
      const double want = model_then_palette[palette_at + i];
      ASSERT_NEAR(got[i], want, 1e-9 * (1 + std::fabs(want)))
          << c.label << " t " << t << " entry " << i / 12 << " element " << i % 12;
    }
  }
}

TEST(ReferencePosePaletteTest, AgreesWithTheTestsFloat64ClipOnTheSyntheticRig) {
  ExpectSamePalettes(SyntheticCase(77));
}

TEST(ReferencePosePaletteTest, AgreesWithTheTestsFloat64ClipOnTheTestCharacters) {
  ExpectSamePalettes(AssetCase("CesiumMan.glb", 0));
  ExpectSamePalettes(AssetCase("RiggedSimple.glb", 0));
}

}  // namespace
}  // namespace skinserve::testing
