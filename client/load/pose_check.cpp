#include "pose_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "pose_workload.h"
#include "skinserve/reference/reference.h"

namespace skinserve::load {
namespace {

constexpr double kAbsolute = 2e-5;  // the pose tests' bound: 2e-5 + 3e-4 (|rest| + |posed|)
constexpr double kRelative = 3e-4;
constexpr double kInf = std::numeric_limits<double>::infinity();

double Length(const double* v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// The worst ratio over `got`'s vectors (`stride` values a vertex, x y z first) of their
// distance from `want`'s to `bound(v, want's x y z)`.
template <typename Bound>
double WorstVectorRatio(std::span<const float> got, const std::vector<double>& want,
                        std::size_t stride, Bound bound) {
  if (got.size() != want.size()) return kInf;
  double worst = 0;
  for (std::size_t v = 0; v < got.size() / stride; ++v) {
    double d[3];
    for (int i = 0; i < 3; ++i) d[i] = got[stride * v + i] - want[stride * v + i];
    const double error = Length(d);
    if (std::isnan(error)) return kInf;
    worst = std::max(worst, error / bound(v, &want[stride * v]));
  }
  return worst;
}

// Tangents' w, +1 or -1, exactly the rest's (every encoding holds it).
double TangentSigns(std::span<const float> got, const std::vector<double>& want) {
  for (std::size_t i = 3; i < got.size() && i < want.size(); i += 4) {
    if (got[i] != want[i]) return kInf;
  }
  return 0;
}

}  // namespace

namespace {

// The answer's positions (and normals, tangents when the workload has them) against the
// float64 ones `posed`, of the rest positions `rest`: the bound of the header.
double VectorsError(const Workload& w, const PoseAnswer& answer, std::span<const double> rest,
                    const ReferenceFrame& posed, const MorphMagnitudes& magnitudes) {
  const auto encoding_error = [&](const double* at) {  // positions: the axes' together
    double e[3];
    for (int i = 0; i < 3; ++i) {
      e[i] = PositionEncodingError(answer.encoding, answer.bounds, i, std::fabs(at[i]));
    }
    return Length(e);
  };
  if (rest.size() != posed.positions.size()) return kInf;
  const double scale = w.pose->ErrorScale();  // a clip stored to a looser bound
  double worst = WorstVectorRatio(
      answer.positions, posed.positions, 3, [&](std::size_t v, const double* want) {
        return scale * (kAbsolute + kRelative * (Length(&rest[3 * v]) + Length(want))) +
               encoding_error(want);
      });
  const auto unit_bound = [&](double magnification) {
    return [&, magnification](std::size_t, const double* want) {
      double e[3];
      for (int i = 0; i < 3; ++i) e[i] = NormalEncodingError(answer.encoding, std::fabs(want[i]));
      return scale * (kAbsolute + kRelative * 2) * magnification + Length(e);
    };
  };
  if (w.normals) {
    worst = std::max(worst, WorstVectorRatio(answer.normals, posed.normals, 3,
                                             unit_bound(magnitudes.normal_magnification)));
  }
  if (w.tangents) {
    worst = std::max(worst, WorstVectorRatio(answer.tangents, posed.tangents, 4,
                                             unit_bound(magnitudes.tangent_magnification)));
    worst = std::max(worst, TangentSigns(answer.tangents, posed.tangents));
  }
  return worst;
}

// --animate FILE: the file's own primitive (as the check read it) skinned in double with the
// file's clip at the frame's time (GltfPoseReference); no morph targets, no tangents.
double GltfPoseAnswerError(const Workload& w, const PoseAnswer& answer) {
  const gltf_reference::RefCharacter& ref = w.pose->gltf->character;
  const gltf_reference::RefFrame frame =
      gltf_reference::RefSkin(ref.primitive, w.pose->ReferencePalette(answer.frame));
  ReferenceFrame posed;
  posed.positions = frame.positions;
  posed.normals = frame.normals;
  return VectorsError(w, answer, ref.primitive.positions, posed, MorphMagnitudes{});
}

}  // namespace

double PoseAnswerError(const Workload& w, const PoseAnswer& answer) {
  if (w.pose->gltf) return GltfPoseAnswerError(w, answer);
  const Mesh& mesh = *w.mesh;
  const std::span<const MorphWeight> morph = w.Morph(answer.frame);
  const std::vector<double> palette = w.pose->ReferencePalette(answer.frame);
  const ReferenceFrame rest = ReferenceMorph(mesh, morph);
  const ReferenceFrame posed = ReferenceSkin(mesh, std::span<const double>(palette), morph);
  return VectorsError(w, answer, rest.positions, posed, ReferenceMorphMagnitudes(mesh, morph));
}

}  // namespace skinserve::load
