#include "skinserve/model/skinning_method.h"

namespace skinserve {

std::string_view MethodName(SkinningMethod method) {
  switch (method) {
    case SkinningMethod::kLinear:
      return "linear";
    case SkinningMethod::kDualQuaternion:
      return "dual-quaternion";
  }
  return "unknown";
}

std::optional<SkinningMethod> ParseMethod(std::string_view name) {
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    if (name == MethodName(method)) return method;
  }
  return std::nullopt;
}

std::string MethodNames(const std::vector<SkinningMethod>& methods) {
  std::string names;
  for (SkinningMethod method : methods) {
    if (!names.empty()) names += ", ";
    names += MethodName(method);
  }
  return names;
}

}  // namespace skinserve
