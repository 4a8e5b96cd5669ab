#include "skinserve/character/character.h"

namespace skinserve {

const AnimationClip* Character::FindClip(const std::string& name) const {
  if (name.empty()) return clips.empty() ? nullptr : &clips.front();
  for (const AnimationClip& clip : clips) {
    if (clip.name == name) return &clip;
  }
  return nullptr;
}

}  // namespace skinserve
