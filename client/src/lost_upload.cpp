#include "skinserve/client/lost_upload.h"

#include <optional>
#include <string_view>

namespace skinserve::client {
namespace {

// The id quoted right after `field` in `message` ("field 'id' ..."), if it is there.
std::optional<std::string> QuotedAfter(std::string_view message, std::string_view field) {
  const std::size_t at = message.find(field);
  if (at == std::string_view::npos) return std::nullopt;
  const std::size_t open = at + field.size();
  if (message.substr(open, 2) != " '") return std::nullopt;
  const std::size_t close = message.find('\'', open + 2);
  if (close == std::string_view::npos) return std::nullopt;
  return std::string(message.substr(open + 2, close - open - 2));
}

}  // namespace

LostUpload LostUploadOf(const Status& status, const std::string& mesh_id) {
  const std::string_view message = status.message();
  if (auto skeleton = QuotedAfter(message, "pose.skeleton_id")) {
    return {.kind = LostUpload::Kind::kSkeleton, .id = *skeleton};
  }
  // "pose.layers[i].clip_id 'C'": the layer's index is in between.
  if (message.find("pose.layers[") != std::string_view::npos) {
    if (auto clip = QuotedAfter(message, "].clip_id")) {
      return {.kind = LostUpload::Kind::kClip, .id = *clip};
    }
  }
  return {.kind = LostUpload::Kind::kMesh, .id = mesh_id};
}

}  // namespace skinserve::client
