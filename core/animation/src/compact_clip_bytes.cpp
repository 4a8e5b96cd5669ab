// CompactClip's canonical bytes (little-endian, fixed field order) and their hash.
#include <fmt/format.h>
#include <openssl/evp.h>

#include <cstring>

#include "clip_id.h"
#include "skinserve/animation/compact_clip.h"

namespace skinserve::animation {
namespace {

class Writer {
 public:
  template <typename T>
  void Put(const T& v) {  // the hosts we build for are little-endian (as Mesh's bytes)
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  template <typename T>
  void PutArray(const std::vector<T>& v) {
    Put(static_cast<uint32_t>(v.size()));
    const auto* p = reinterpret_cast<const uint8_t*>(v.data());
    bytes_.insert(bytes_.end(), p, p + v.size() * sizeof(T));
  }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

}  // namespace

std::vector<uint8_t> CompactClip::Serialize() const {
  Writer w;
  constexpr char kMagic[8] = {'S', 'S', 'C', 'L', 'I', 'P', '2', '\0'};
  for (char c : kMagic) w.Put(c);
  w.PutArray(std::vector<char>(name.begin(), name.end()));
  w.Put(duration);
  w.Put(max_error_mm);  // the bound is part of what the clip is
  w.Put(joint_count);
  w.Put(weight_count);
  w.PutArray(weight_groups);
  w.PutArray(times);
  w.PutArray(key_times);
  w.Put(static_cast<uint32_t>(tracks.size()));
  // 7 bytes a track (8 packed: its bits): what it is and how many keys; where its data lies follows
  // from the tracks before it, so offsets are not part of the bytes (nor of the id).
  for (const CompactTrack& t : tracks) {
    w.Put(static_cast<uint8_t>(
        static_cast<unsigned>(t.path) | static_cast<unsigned>(t.interpolation) << 2 |
        static_cast<unsigned>(t.format) << 4 | (t.key_times == kAllKeyTimes ? 0u : 1u) << 7));
    if (t.format == TrackFormat::kRangePacked || t.format == TrackFormat::kSmallestThreePacked)
      w.Put(t.bits);
    w.Put(t.width);
    w.Put(t.joint);
    w.Put(static_cast<uint16_t>(t.key_count));  // at most kMaxClipKeyTimes
  }
  w.PutArray(floats);
  w.PutArray(words);
  w.PutArray(largest);
  w.PutArray(packed);
  return w.Take();
}

std::string ClipId(std::span<const uint8_t> bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(bytes.data(), bytes.size(), digest, &length, EVP_sha256(), nullptr);
  std::string hex;
  hex.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

}  // namespace skinserve::animation
