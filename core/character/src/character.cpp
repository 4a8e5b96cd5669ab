#include "skinserve/character/character.h"

namespace skinserve {

std::string_view StoredTypeName(StoredType type) {
  switch (type) {
    case StoredType::kNone:
      return "none";
    case StoredType::kFloat:
      return "FLOAT";
    case StoredType::kByte:
      return "BYTE";
    case StoredType::kUnsignedByte:
      return "UNSIGNED_BYTE";
    case StoredType::kShort:
      return "SHORT";
    case StoredType::kUnsignedShort:
      return "UNSIGNED_SHORT";
  }
  return "unknown";
}

const AnimationClip* Character::FindClip(const std::string& name) const {
  if (name.empty()) return clips.empty() ? nullptr : &clips.front();
  for (const AnimationClip& clip : clips) {
    if (clip.name == name) return &clip;
  }
  return nullptr;
}

}  // namespace skinserve
