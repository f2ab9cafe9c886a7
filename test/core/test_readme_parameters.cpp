// README.md's and doc/usage.md's parameter tables against the core's parameter table (parameters.h): every
// parameter of the user tier is named in a row of a README table and no advanced one is; every parameter
// is named in a row of doc/usage.md's All parameters, whose tier column is the table's; where a row gives a
// default for it, that default is the core's. Fails when the README or the doc drifts from the core.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/parameters.h"

namespace arl = along_route_localization;

namespace
{

/// What one README table row says of one parameter: its default as written ("" when the row gives
/// none for it) and the row itself, for messages.
struct ReadmeEntry
{
  std::string default_text;
  std::string row;
  std::string fourth_cell;  ///< trimmed; in doc/usage.md's tables, the tier ("user" or "advanced")
};

std::string trim(const std::string& s)
{
  const auto begin = s.find_first_not_of(" \t");
  if (begin == std::string::npos)
    return "";
  const auto end = s.find_last_not_of(" \t");
  return s.substr(begin, end - begin + 1);
}

std::vector<std::string> split(const std::string& s, const std::string& separator)
{
  std::vector<std::string> parts;
  size_t at = 0;
  for (size_t next; (next = s.find(separator, at)) != std::string::npos; at = next + separator.size())
    parts.push_back(s.substr(at, next - at));
  parts.push_back(s.substr(at));
  return parts;
}

/// The rows "| `name`[, `name` ...] [*dyn*] | unit | default[, default ...] | meaning |" of README.md,
/// by name. A row naming n parameters gives their defaults in order when its default cell has n values.
std::map<std::string, ReadmeEntry> readmeParameterRows(const std::string& path)
{
  std::map<std::string, ReadmeEntry> rows;
  std::ifstream file(path);
  for (std::string line; std::getline(file, line);)
  {
    if (line.compare(0, 3, "| `") != 0)
      continue;
    const std::vector<std::string> cells = split(line, "|");
    if (cells.size() < 5)  // "", name, unit, default, meaning..., ""
      continue;
    std::vector<std::string> names;
    const std::vector<std::string> ticks = split(cells[1], "`");
    for (size_t i = 1; i < ticks.size(); i += 2)  // the text between each pair of backticks
      names.push_back(ticks[i]);
    std::vector<std::string> defaults = split(cells[3], ",");
    for (std::string& d : defaults)
    {
      d = trim(d);
      if (d.size() >= 2 && d.front() == '`' && d.back() == '`')
        d = d.substr(1, d.size() - 2);
      d = d.substr(0, d.find(' '));  // "0 (off)" -> "0"
    }
    for (size_t i = 0; i < names.size(); ++i)
      rows[names[i]] = { defaults.size() == names.size() ? defaults[i] : "", line, trim(cells[4]) };
  }
  return rows;
}

/// Whether `written` (as in the README: "0.85", "57.3", "true", "divisive") is the default of `spec`: a
/// number equal to it to the precision written (57.3 for 57.2958), a boolean or choice the same name.
bool sameDefault(const arl::ParameterSpec& spec, const std::string& written, std::string* core)
{
  const arl::ParameterSet defaults;
  if (spec.type == arl::ParameterType::kChoice)
  {
    *core = spec.get_choice(defaults);
    return written == *core;
  }
  const double value = spec.get_number(defaults);
  if (spec.type == arl::ParameterType::kBool)
  {
    *core = value != 0 ? "true" : "false";
    return written == *core;
  }
  std::ostringstream text;
  text << value;
  *core = text.str();
  char* end = nullptr;
  const double given = std::strtod(written.c_str(), &end);
  if (written.empty() || *end != '\0')
    return false;
  const auto dot = written.find('.');
  const int decimals = dot == std::string::npos ? 0 : static_cast<int>(written.size() - dot - 1);
  return std::fabs(given - value) <= 0.5 * std::pow(10.0, -decimals) + 1e-9 * std::fabs(value);
}

const std::string kReadme = std::string(ALONG_ROUTE_SOURCE_DIR) + "/README.md";
const std::string kUsage = std::string(ALONG_ROUTE_SOURCE_DIR) + "/doc/usage.md";

TEST(ReadmeParameters, TheRowReaderTakesNamesAndDefaultsInOrder)
{
  // The reader on rows written as the README writes them, so the check below means what it says.
  const std::string path = ::testing::TempDir() + "readme_rows_test.md";
  std::ofstream(path) << "| name | unit | default | meaning |\n|---|---|---|---|\n"
                      << "| `output_width`, `output_height` *dyn* | px | 64, 32 | size |\n"
                      << "| `normalization` *dyn* | | `divisive` | eq. 3 |\n"
                      << "| `min_time_gap` | s | 0 (off) | since the last keyframe |\n"
                      << "| `a`, `b` | | see `x` | no defaults |\n";
  const auto rows = readmeParameterRows(path);
  std::remove(path.c_str());
  ASSERT_EQ(rows.size(), 6u);  // a, b, output_width, output_height, normalization, min_time_gap
  EXPECT_EQ(rows.at("output_width").default_text, "64");
  EXPECT_EQ(rows.at("output_height").default_text, "32");
  EXPECT_EQ(rows.at("normalization").default_text, "divisive");
  EXPECT_EQ(rows.at("min_time_gap").default_text, "0");
  EXPECT_EQ(rows.at("a").default_text, "");
  EXPECT_EQ(rows.at("b").default_text, "");
  // Defaults compared to the precision written: 57.3 is 1 rad in degrees, 57.2 is not.
  const arl::ParameterSpec* fov = arl::findParameter("horizontal_fov_deg");
  ASSERT_NE(fov, nullptr);
  std::string core;
  EXPECT_TRUE(sameDefault(*fov, "57.3", &core));
  EXPECT_FALSE(sameDefault(*fov, "57.2", &core));
  EXPECT_FALSE(sameDefault(*arl::findParameter("skip_penalty"), "1.0", &core));
  EXPECT_TRUE(sameDefault(*arl::findParameter("skip_penalty"), "0.85", &core));
}

TEST(ReadmeParameters, EachUserTierParameterIsInAReadmeTableWithTheCoreDefaultAndNoAdvancedOneIs)
{
  const auto rows = readmeParameterRows(kReadme);
  ASSERT_FALSE(rows.empty()) << "no parameter table rows read from " << kReadme;
  int defaults_checked = 0, user = 0;
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    const auto row = rows.find(spec.name);
    if (spec.tier == arl::ParameterTier::kAdvanced)
    {
      EXPECT_TRUE(row == rows.end()) << spec.name << " is advanced and in a README table: " << row->second.row;
      continue;
    }
    ++user;
    if (row == rows.end())
    {
      ADD_FAILURE() << spec.name << " (" << arl::toString(spec.group) << ") is in no parameter table row of "
                    << kReadme;
      continue;
    }
    if (row->second.default_text.empty())
      continue;
    std::string core;
    EXPECT_TRUE(sameDefault(spec, row->second.default_text, &core))
        << spec.name << ": README says " << row->second.default_text << ", the core table " << core << "\n  "
        << row->second.row;
    ++defaults_checked;
  }
  // Every user row gives its default; a reader that stopped finding them would pass vacuously.
  EXPECT_EQ(33, user);  // 6 + 14 + 4 + 9 (test_parameters.cpp, ParameterTiers)
  EXPECT_EQ(user, defaults_checked);
}

TEST(ReadmeParameters, EveryParameterIsInTheDocsFullTableWithItsTierAndTheCoreDefault)
{
  const auto rows = readmeParameterRows(kUsage);
  ASSERT_FALSE(rows.empty()) << "no parameter table rows read from " << kUsage;
  int defaults_checked = 0;
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    const auto row = rows.find(spec.name);
    if (row == rows.end())
    {
      ADD_FAILURE() << spec.name << " (" << arl::toString(spec.group) << ") is in no parameter table row of "
                    << kUsage;
      continue;
    }
    EXPECT_EQ(arl::toString(spec.tier), row->second.fourth_cell) << spec.name << ": " << row->second.row;
    std::string core;
    EXPECT_TRUE(sameDefault(spec, row->second.default_text, &core))
        << spec.name << ": doc/usage.md says " << row->second.default_text << ", the core table " << core << "\n  "
        << row->second.row;
    ++defaults_checked;
  }
  EXPECT_EQ(arl::parameterTable().size(), static_cast<size_t>(defaults_checked));
  // A removed parameter is named there as removed, not in a row.
  for (const arl::RemovedParameter& removed : arl::removedParameters())
    EXPECT_TRUE(rows.find(removed.name) == rows.end()) << removed.name << " is removed and in a row";
}

}  // namespace
