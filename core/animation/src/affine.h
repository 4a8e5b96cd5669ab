// Row-major 3x4 affine products shared by the jobs.
#pragma once

#include "skinserve/animation/transform.h"

namespace skinserve::animation {

// out = a * b (out must not alias a or b).
void MultiplyAffine(const Affine& a, const Affine& b, Affine& out);

}  // namespace skinserve::animation
