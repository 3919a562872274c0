// The documentation against the code: docs/rod_model.md names only symbols that exist where it says,
// docs/architecture.md only names and paths that exist, docs/ros_api.md lists exactly the topics and
// services of include/hydrojet_control/ros/names.h, the README stays short, and every relative link
// in README.md and docs/*.md resolves.
#include <gtest/gtest.h>

#include <dirent.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "hydrojet_control/ros/names.h"

namespace {

const std::string kRoot = HYDROJET_SOURCE_DIR;

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

/// Cells of a markdown table row "| a | b |" (trimmed), empty when the line is not a row.
std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> out;
  if (line.empty() || line[0] != '|') return out;
  std::stringstream ss(line.substr(1));
  for (std::string c; std::getline(ss, c, '|');) {
    const size_t a = c.find_first_not_of(" \t"), b = c.find_last_not_of(" \t");
    out.push_back(a == std::string::npos ? "" : c.substr(a, b - a + 1));
  }
  return out;
}

/// Every `code span` in a cell.
std::vector<std::string> code_spans(const std::string& cell) {
  std::vector<std::string> out;
  static const std::regex re("`([^`]+)`");
  for (std::sregex_iterator it(cell.begin(), cell.end(), re), end; it != end; ++it) out.push_back((*it)[1]);
  return out;
}

/// First-column names of the table under the section "## <title>" of a markdown text.
std::set<std::string> table_names(const std::string& text, const std::string& title) {
  std::set<std::string> out;
  bool in = false;
  for (const std::string& l : lines_of(text)) {
    if (l.rfind("## ", 0) == 0) in = l == "## " + title;
    if (!in) continue;
    const auto c = cells(l);
    if (c.empty()) continue;
    for (const std::string& n : code_spans(c[0])) out.insert(n);
  }
  return out;
}

TEST(Docs, RodModelNamesSymbolsThatExistInTheNamedFiles) {
  const std::string text = read_file(kRoot + "/docs/rod_model.md");
  ASSERT_FALSE(text.empty()) << "docs/rod_model.md missing";
  int rows = 0;
  bool in_table = false;
  for (const std::string& l : lines_of(text)) {
    const auto c = cells(l);
    if (c.size() >= 4 && c[0] == "Eq." && c[2] == "File" && c[3] == "Symbol") {
      in_table = true;
      continue;
    }
    if (!in_table || c.size() < 4 || c[2].find("---") != std::string::npos) continue;
    const auto files = code_spans(c[2]);
    const auto symbols = code_spans(c[3]);
    ASSERT_EQ(files.size(), 1u) << "row without exactly one `file`: " << l;
    ASSERT_FALSE(symbols.empty()) << "row without a `symbol`: " << l;
    const std::string source = read_file(kRoot + "/" + files[0]);
    ASSERT_FALSE(source.empty()) << files[0] << " (named in docs/rod_model.md) does not exist";
    for (const std::string& s : symbols) {
      const std::regex word("(^|[^A-Za-z0-9_])" +
                            std::regex_replace(s, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
                            "($|[^A-Za-z0-9_])");
      EXPECT_TRUE(std::regex_search(source, word))
          << "`" << s << "` not found in " << files[0] << " (row: " << l << ")";
    }
    ++rows;
  }
  EXPECT_GE(rows, 15) << "docs/rod_model.md: the table | Eq. | What | File | Symbol | has too few rows";
}

TEST(Docs, RosApiListsExactlyTheTopicsAndServicesOfTheNodes) {
  const std::string text = read_file(kRoot + "/docs/ros_api.md");
  ASSERT_FALSE(text.empty()) << "docs/ros_api.md missing";
  const std::set<std::string> topics(std::begin(hydrojet::names::kTopics), std::end(hydrojet::names::kTopics));
  const std::set<std::string> services(std::begin(hydrojet::names::kServices), std::end(hydrojet::names::kServices));
  EXPECT_EQ(table_names(text, "Topics"), topics);
  EXPECT_EQ(table_names(text, "Services"), services);
}

TEST(Docs, ReadmeIsShortAndStartsWithTheTwoCommands) {
  const auto lines = lines_of(read_file(kRoot + "/README.md"));
  EXPECT_LE(lines.size(), 200u);
  const std::string text = read_file(kRoot + "/README.md");
  EXPECT_NE(text.find("scripts/demo"), std::string::npos);
  EXPECT_NE(text.find("scripts/test"), std::string::npos);
}

TEST(Docs, RelativeLinksResolve) {
  std::vector<std::string> files = {"README.md"};
  if (DIR* d = opendir((kRoot + "/docs").c_str())) {
    while (dirent* e = readdir(d)) {
      const std::string n = e->d_name;
      if (n.size() > 3 && n.substr(n.size() - 3) == ".md") files.push_back("docs/" + n);
    }
    closedir(d);
  }
  static const std::regex link(R"(\]\(([^)#\s]+)(#[^)]*)?\))");
  int checked = 0;
  for (const std::string& f : files) {
    const std::string text = read_file(kRoot + "/" + f);
    const std::string dir = f.find('/') == std::string::npos ? "" : f.substr(0, f.rfind('/') + 1);
    for (std::sregex_iterator it(text.begin(), text.end(), link), end; it != end; ++it) {
      const std::string target = (*it)[1];
      if (target.find("://") != std::string::npos || target.rfind("mailto:", 0) == 0) continue;
      std::ifstream probe(kRoot + "/" + dir + target);
      EXPECT_TRUE(probe.good()) << f << " links to " << target << ", which does not exist";
      ++checked;
    }
  }
  EXPECT_GT(checked, 10);
}

}  // namespace

namespace {

/// The text the code names live in: sources, headers, configuration, launch files, messages, scripts.
const std::string& code_corpus() {
  static const std::string corpus = [] {
    std::string all;
    for (const char* dir : {"src", "include", "config", "launch", "cfg", "msg", "action", "scripts", "python"})
      for (const auto& e : std::filesystem::recursive_directory_iterator(kRoot + "/" + dir))
        if (e.is_regular_file()) all += read_file(e.path().string()) + "\n";
    return all + read_file(kRoot + "/CMakeLists.txt");
  }();
  return corpus;
}

bool names_word(const std::string& text, const std::string& name) {
  const std::regex word("(^|[^A-Za-z0-9_])" + std::regex_replace(name, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
                        "($|[^A-Za-z0-9_])");
  return std::regex_search(text, word);
}

}  // namespace

// Every code span of docs/architecture.md that is a path (under a top-level folder of the
// repository) names a file or folder that exists; every one that is a name (identifier, A::B, a
// topic or a flag) occurs in the code, each part of a qualified name as a word.
TEST(Docs, ArchitectureNamesExist) {
  std::string text;  // the prose and tables: fenced blocks (drawings) left out
  bool fenced = false;
  for (const std::string& l : lines_of(read_file(kRoot + "/docs/architecture.md"))) {
    if (l.rfind("```", 0) == 0) fenced = !fenced;
    if (!fenced && l.rfind("```", 0) != 0) text += l + "\n";
  }
  ASSERT_FALSE(text.empty()) << "docs/architecture.md missing";
  static const std::regex name_like(R"(^[~/-]*[A-Za-z_][A-Za-z0-9_:./-]*(\(\))?$)");
  static const std::set<std::string> roots = {"src",   "include", "docs", "config", "launch", "scripts", "test",
                                              "bench", "cmake",   "cfg",  "msg",    "action", "util",    "python"};
  int checked = 0;
  for (const std::string& line : lines_of(text))
    for (const std::string& span : code_spans(line)) {
      std::string s = span;
      if (s.find(' ') != std::string::npos) s = s.substr(0, s.find(' '));  // "scripts/check_core --quick"
      if (!std::regex_match(s, name_like)) continue;                       // a formula, a message template
      if (s.size() > 2 && s.compare(s.size() - 2, 2, "()") == 0) s.resize(s.size() - 2);
      const std::string first = s.substr(0, s.find('/'));
      if (s.find('/') != std::string::npos && roots.count(first)) {
        const std::string path = first == "util" ? "include/hydrojet_control/" + s : s;
        EXPECT_TRUE(std::filesystem::exists(kRoot + "/" + path)) << "`" << span << "`: no such path";
      } else if (s.find("::") != std::string::npos) {
        for (size_t a = 0, b; a < s.size(); a = b + 2) {
          b = s.find("::", a);
          if (b == std::string::npos) b = s.size();
          EXPECT_TRUE(names_word(code_corpus(), s.substr(a, b - a))) << "`" << span << "`: " << s.substr(a, b - a);
        }
      } else {
        EXPECT_NE(code_corpus().find(s.substr(s.find_first_not_of("~"))), std::string::npos)
            << "`" << span << "` does not occur in the code";
      }
      ++checked;
    }
  EXPECT_GT(checked, 100) << "the check found too few names to be meaningful";
}
