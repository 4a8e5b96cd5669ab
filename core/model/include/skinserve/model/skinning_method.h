// The skinning method of a frame: linear blend skinning (the default, the paper's) or
// dual-quaternion skinning, which keeps volume on twisting joints but needs rigid joints.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace skinserve {

enum class SkinningMethod {
  kLinear,
  kDualQuaternion,
};

// "linear" or "dual-quaternion": the names of the CLI, the load client and the errors.
std::string_view MethodName(SkinningMethod method);
// The inverse of MethodName; nullopt for any other text.
std::optional<SkinningMethod> ParseMethod(std::string_view name);
// "linear, dual-quaternion": for usage lines and errors.
std::string MethodNames(const std::vector<SkinningMethod>& methods);

}  // namespace skinserve
