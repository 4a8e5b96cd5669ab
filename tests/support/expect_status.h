// The check every bad-input test makes: an error's code, and the field or limit its message
// names.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "skinserve/model/status.h"

namespace skinserve::testing {

// Expects `s` to carry `code` and a message containing `needle`.
inline void ExpectStatus(const Status& s, StatusCode code, const std::string& needle) {
  EXPECT_EQ(s.code(), code) << s.ToString();
  EXPECT_NE(s.message().find(needle), std::string::npos)
      << "message: " << s.message() << "\nexpected to contain: " << needle;
}

}  // namespace skinserve::testing
