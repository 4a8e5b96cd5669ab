// What a load run sends: a mesh (synthetic, deterministic from a seed, or a glTF
// character's) and palettes that change every frame, plus the local Mesh used to check
// sampled answers.
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/character/rest_encoding_choice.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/model/status.h"

namespace skinserve::load {

inline constexpr int kDistinctPalettes = 32;

struct PoseWorkload;  // pose_workload.h

struct Workload {
  uint32_t vertices = 0;
  uint32_t bones = 0;
  uint32_t joints = 77;
  bool normals = false;
  bool tangents = false;                            // asked for back (want_tangents) and checked
  SkinningMethod method = SkinningMethod::kLinear;  // asked of the server, checked locally
  std::shared_ptr<const MeshArrays> arrays;         // shared by every stream's client
  std::shared_ptr<const Mesh> mesh;                 // for the float64 reference checks
  // A glTF workload's triangles (3 indices each into the merged vertices, every part's
  // renumbered), for renderers; empty for the synthetic mesh, which has no faces.
  std::vector<uint32_t> indices;
  // Asked of the server at upload (--rest-encoding); `mesh` then holds the values the
  // quantized stream decodes to, which is what the server skins.
  RestEncoding rest_encoding = RestEncoding::kFloat32;
  // A glTF workload: the rest encoding its file's stored types ask for (RestEncodingFromFile
  // over the uploaded primitives); unset for the synthetic mesh.
  std::optional<RestEncodingChoice> file_rest_encoding;
  // Why rest_encoding is what it is (ChooseRestEncoding), one line for the run's output.
  std::string rest_encoding_reason;
  std::vector<std::vector<float>> palettes;  // frame f uses palettes[f % size]
  // Frame f's sparse morph target weights: morph_weights[f % size]; empty: the frames carry
  // none (a mesh without targets, or --morph-active 0).
  std::vector<std::vector<MorphWeight>> morph_weights;
  // --animate: frames carry this pose (the synthetic skeleton and clip on the server)
  // instead of a palette, and checks evaluate it in float64; null: palettes.
  std::shared_ptr<PoseWorkload> pose;

  const std::vector<float>& Palette(uint64_t frame) const {
    return palettes[frame % palettes.size()];
  }
  std::span<const MorphWeight> Morph(uint64_t frame) const {
    if (morph_weights.empty()) return {};
    return morph_weights[frame % morph_weights.size()];
  }
  const std::vector<MorphWeight>& MorphVector(uint64_t frame) const {
    return morph_weights[frame % morph_weights.size()];
  }
};

// Synthetic morph targets of a load run (--morph-targets, --morph-coverage, --morph-active):
// `targets` random targets (AddSyntheticMorphTargets) each moving about `coverage` of the
// vertices (normals too when the mesh has them), and per frame `active` of them with
// random weights (MakeMorphWeights). targets = 0: no morph targets.
struct MorphWorkload {
  uint32_t targets = 0;
  double coverage = 0.1;
  uint32_t active = 4;
};

// Stores the workload's mesh as `encoding` (its reference mesh rebuilt from the arrays; a
// quantized one drops the mesh's tangents unless `tangents` are asked back): INVALID_ARGUMENT
// as the server would answer (e.g. a mesh with morph targets).
Status SetRestEncoding(Workload* w, RestEncoding encoding);

// Picks the workload's rest encoding as every tool does (DecideRestEncoding: `asked`, else
// file_rest_encoding for a glTF workload, else float32), applies it (SetRestEncoding) and
// sets rest_encoding_reason.
Status ChooseRestEncoding(Workload* w, std::optional<RestEncoding> asked);

// Dual-quaternion workloads get rigid palettes (MakeRigidPalette): the method refuses the
// synthetic palettes' scale. `tangents` (with normals): the mesh has tangents (and its
// morph targets tangent deltas), asked for back.
Workload MakeWorkload(uint32_t vertices, uint32_t bones, uint32_t joints, bool normals,
                      uint64_t seed, SkinningMethod method = SkinningMethod::kLinear,
                      const MorphWorkload& morph = {}, bool tangents = false);

// Frames of clip time per second in a glTF workload's palettes.
inline constexpr double kGltfWorkloadFps = 30.0;

// The whole character of the glTF file at `path` as one mesh (or only primitive
// `primitive` when >= 0): primitives that share a skin are concatenated with the rigid
// parts (CharacterMeshes), and several meshes are concatenated too, each mesh's joint
// indices shifted past the meshes before it, so that one palette (the meshes' palettes one
// after another) skins the whole character in one request per frame. Palettes sample the file's
// first clip every 1 / kGltfWorkloadFps s over its duration, so frame f shows time f / 30 s wrapped
// around the clip. INVALID_ARGUMENT (naming the file) when it does not import, has no such
// primitive or no clip, its meshes have more than 65535 palette entries together, or `normals` is
// asked of a mesh without them, or `tangents` of a character whose primitives do not all have
// them. Morph targets of the meshes are kept (concatenated like the
// vertices); each frame carries their weights at its clip time (the clip's `weights`
// channels, else the file's default weights), as `animate` sends them.
Result<Workload> MakeGltfWorkload(const std::string& path, int primitive, bool normals,
                                  bool tangents = false);

}  // namespace skinserve::load
