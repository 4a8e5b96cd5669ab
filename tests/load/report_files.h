// Reading the load client's report files back in tests: CSV and JSON must hold the same
// columns with the same values.
#pragma once

#include <string>

namespace skinserve::load {

// Every JSON leaf (maps such as `errors` as one) is a CSV column of the same dotted name
// and value, and the other way round; rows in the same order. Fails the current test.
void ExpectCsvMatchesJson(const std::string& csv_path, const std::string& json_path);

}  // namespace skinserve::load
