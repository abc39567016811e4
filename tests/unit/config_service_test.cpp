// rack-gui's configuration service (tools/gui/config_service.h): which files a browser
// may read and write (only host files directly in a served directory, no symbolic
// links, no other names), that a text is saved only when rackd --check accepts it
// (with its errors at their line otherwise), and that nothing else is left behind.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "config_service.h"

namespace rack::gui {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kValid =
    "# a comment that must survive\n"
    "host: t\n"
    "components:\n"
    "  - name: gen\n"
    "    class: Generator\n"
    "    data_task: {priority: 60, period_ms: 10}   # 100 Hz\n";

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class ConfigServiceTest : public ::testing::Test {
 protected:
  ConfigServiceTest() {
    char tmpl[] = "/tmp/rack-config-test-XXXXXX";
    root_ = ::mkdtemp(tmpl);
    served_ = root_ / "served";
    fs::create_directories(served_ / "sub");
    std::ofstream(served_ / "host.yaml") << kValid;
    std::ofstream(root_ / "outside.yaml") << kValid;
    fs::create_symlink(root_ / "outside.yaml", served_ / "link.yaml");
    ConfigServiceConfig c;
    c.dirs = {served_.string()};
    c.rackd_path = RACK_RACKD_PATH;
    service_ = std::make_unique<ConfigService>(c, [](uint64_t, std::string) {});
  }
  ~ConfigServiceTest() override {
    service_.reset();
    fs::remove_all(root_);
  }
  json call(const json& request) { return json::parse(service_->handle(request.dump())); }
  std::size_t entries() const {
    std::size_t n = 0;
    for (const auto& e : fs::directory_iterator(served_)) n += (e.is_regular_file() || e.is_symlink()) ? 1u : 0u;
    return n;
  }

  fs::path root_, served_;
  std::unique_ptr<ConfigService> service_;
};

TEST_F(ConfigServiceTest, RecognisesItsMessages) {
  EXPECT_TRUE(ConfigService::handles(R"({"op":"config_files"})"));
  EXPECT_FALSE(ConfigService::handles(R"({"op":"switch"})"));
  EXPECT_FALSE(ConfigService::handles("not json"));
  EXPECT_FALSE(ConfigService::handles(R"(["config_files"])"));
  EXPECT_FALSE(ConfigService::handles(std::string(100000, '[')));
}

TEST_F(ConfigServiceTest, ServesOnlyHostFilesDirectlyInItsDirectories) {
  std::string why;
  EXPECT_EQ(service_->served_file((served_ / "host.yaml").string(), why), (served_ / "host.yaml").string()) << why;
  EXPECT_EQ(service_->served_file((served_ / "new.yml").string(), why), (served_ / "new.yml").string()) << why;
  for (const fs::path& bad :
       {root_ / "outside.yaml", served_ / "sub" / "x.yaml", served_ / ".." / "outside.yaml", served_ / "link.yaml",
        served_ / "notes.txt", served_ / ".hidden.yaml", fs::path("host.yaml"), served_ / "a b.yaml"}) {
    why.clear();
    EXPECT_EQ(service_->served_file(bad.string(), why), "") << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
  const json r = call({{"op", "config_load"}, {"file", (served_ / "link.yaml").string()}, {"id", 7}});
  EXPECT_EQ(r["ok"], false);
  EXPECT_EQ(r["id"], 7);
  EXPECT_NE(r["error"].get<std::string>().find("symbolic links"), std::string::npos) << r;
}

TEST_F(ConfigServiceTest, ListsAndLoads) {
  const json files = call({{"op", "config_files"}});
  ASSERT_EQ(files["ok"], true) << files;
  ASSERT_EQ(files["dirs"].size(), 1u);
  EXPECT_EQ(files["dirs"][0]["dir"], served_.string());
  ASSERT_EQ(files["dirs"][0]["files"].size(), 2u) << files;  // host.yaml and link.yaml (refused when used)
  const json load = call({{"op", "config_load"}, {"file", (served_ / "host.yaml").string()}});
  ASSERT_EQ(load["ok"], true) << load;
  EXPECT_EQ(load["text"], kValid);
}

TEST_F(ConfigServiceTest, SavesOnlyWhatRackdAccepts) {
  const std::string file = (served_ / "host.yaml").string();
  std::string bad = kValid;
  bad.replace(bad.find("priority: 60"), 12, "priority: 300");
  const json refused = call({{"op", "config_save"}, {"file", file}, {"text", bad}});
  ASSERT_EQ(refused["ok"], true) << refused;
  EXPECT_EQ(refused["valid"], false);
  EXPECT_EQ(refused["saved"], false);
  ASSERT_EQ(refused["errors"].size(), 1u) << refused.dump();
  EXPECT_EQ(refused["errors"][0]["line"], 6) << refused.dump();
  EXPECT_EQ(refused["errors"][0]["column"], 27);
  // The message names the file, never the temporary copy that was checked.
  EXPECT_EQ(refused["errors"][0]["message"].get<std::string>().find(".rack-gui-"), std::string::npos) << refused;
  EXPECT_EQ(slurp(file), kValid);  // untouched
  EXPECT_EQ(entries(), 2u);        // no temporary file left

  std::string good = kValid;
  good.replace(good.find("priority: 60"), 12, "priority: 65");
  const json saved = call({{"op", "config_save"}, {"file", file}, {"text", good}});
  ASSERT_EQ(saved["ok"], true) << saved;
  EXPECT_EQ(saved["valid"], true) << saved;
  EXPECT_EQ(saved["saved"], true);
  EXPECT_EQ(slurp(file), good);
  EXPECT_EQ(entries(), 2u);

  // A check never writes.
  const json checked = call({{"op", "config_check"}, {"file", file}, {"text", bad}});
  EXPECT_EQ(checked["valid"], false);
  EXPECT_EQ(slurp(file), good);
  // Outside the served directory: refused before anything is written.
  const json outside = call({{"op", "config_save"}, {"file", (root_ / "outside.yaml").string()}, {"text", good}});
  EXPECT_EQ(outside["ok"], false);
  EXPECT_EQ(slurp(root_ / "outside.yaml"), kValid);
}

// The diff is against the file on disk: a file changed on disk after the client loaded
// it (another editor) is reported by a check and not overwritten by a save made against
// the old text; a save against the present version goes through and gives the new one.
TEST_F(ConfigServiceTest, ASaveAgainstATextNoLongerOnDiskIsRefused) {
  const std::string file = (served_ / "host.yaml").string();
  const json load = call({{"op", "config_load"}, {"file", file}});
  ASSERT_EQ(load["ok"], true) << load;
  const std::string loaded = load["disk_version"].get<std::string>();
  ASSERT_FALSE(loaded.empty());
  std::string mine = kValid;
  mine.replace(mine.find("priority: 60"), 12, "priority: 65");
  // Someone else changes the file meanwhile.
  std::string theirs = kValid;
  theirs += "# their change\n";
  {
    const std::string other = (served_ / ".other.tmp").string();
    std::ofstream(other) << theirs;
    fs::rename(other, file);  // a new inode, as editors save
  }
  const json checked = call({{"op", "config_check"}, {"file", file}, {"text", mine}, {"base_version", loaded}});
  EXPECT_EQ(checked["valid"], true) << checked;
  EXPECT_EQ(checked["disk_changed"], true) << checked;
  const json refused = call({{"op", "config_save"}, {"file", file}, {"text", mine}, {"base_version", loaded}});
  ASSERT_EQ(refused["ok"], true) << refused;
  EXPECT_EQ(refused["saved"], false) << refused;
  EXPECT_NE(refused["save_error"].get<std::string>().find("changed on disk since it was loaded"), std::string::npos);
  EXPECT_EQ(slurp(file), theirs) << "their change is kept";
  EXPECT_EQ(entries(), 2u) << "no temporary file left";
  // Loaded again: the save goes through and answers the new version.
  const std::string now = call({{"op", "config_load"}, {"file", file}})["disk_version"].get<std::string>();
  EXPECT_NE(now, loaded);
  const json saved = call({{"op", "config_save"}, {"file", file}, {"text", mine}, {"base_version", now}});
  EXPECT_EQ(saved["saved"], true) << saved;
  EXPECT_EQ(saved["disk_changed"], false);
  EXPECT_EQ(slurp(file), mine);
  EXPECT_NE(saved["disk_version"].get<std::string>(), now);
}

// A host file above one WebSocket message (64 KiB): sent in parts (config_part), then
// checked and saved as one text; parts out of order, an unknown or incomplete upload,
// and a text above a host file's 1 MiB are refused and drop the upload.
TEST_F(ConfigServiceTest, ATextAboveOneMessageIsSentInParts) {
  const std::string file = (served_ / "host.yaml").string();
  std::string big = kValid;
  while (big.size() < 200 * 1024) big += "# padding: a comment line that makes the file larger than one message\n";
  big.replace(big.find("priority: 60"), 12, "priority: 61");
  constexpr std::size_t kPart = 48 * 1024;
  const std::size_t n = (big.size() + kPart - 1) / kPart;
  ASSERT_GE(n, 4u);
  auto send = [&](const std::string& upload) {
    for (std::size_t i = 0; i < n; ++i) {
      const json r = call({{"op", "config_part"},
                           {"upload", upload},
                           {"index", i},
                           {"count", n},
                           {"text", big.substr(i * kPart, kPart)}});
      if (r["ok"] != true || r["received"] != i + 1) return r;
    }
    return json{{"ok", true}};
  };
  ASSERT_EQ(send("a1")["ok"], true);
  const json checked = call({{"op", "config_check"}, {"file", file}, {"upload", "a1"}});
  ASSERT_EQ(checked["ok"], true) << checked;
  EXPECT_EQ(checked["valid"], true) << checked;
  EXPECT_EQ(slurp(file), kValid) << "a check never writes";
  const json again = call({{"op", "config_save"}, {"file", file}, {"upload", "a1"}});
  EXPECT_EQ(again["ok"], false) << "an upload is used once: " << again;
  ASSERT_EQ(send("a2")["ok"], true);
  const json saved = call({{"op", "config_save"}, {"file", file}, {"upload", "a2"}});
  ASSERT_EQ(saved["ok"], true) << saved;
  EXPECT_EQ(saved["saved"], true) << saved;
  EXPECT_EQ(slurp(file), big);
  EXPECT_EQ(entries(), 2u);

  // Out of order: refused, and the upload is gone.
  ASSERT_EQ(call({{"op", "config_part"}, {"upload", "b"}, {"index", 0}, {"count", 3}, {"text", "x"}})["ok"], true);
  const json skipped = call({{"op", "config_part"}, {"upload", "b"}, {"index", 2}, {"count", 3}, {"text", "y"}});
  EXPECT_EQ(skipped["ok"], false);
  EXPECT_NE(skipped["error"].get<std::string>().find("out of order (expected part 1 of 3)"), std::string::npos)
      << skipped;
  EXPECT_EQ(call({{"op", "config_part"}, {"upload", "b"}, {"index", 1}, {"count", 3}, {"text", "y"}})["ok"], false);
  // Incomplete: refused.
  ASSERT_EQ(call({{"op", "config_part"}, {"upload", "c"}, {"index", 0}, {"count", 2}, {"text", "x"}})["ok"], true);
  const json incomplete = call({{"op", "config_save"}, {"file", file}, {"upload", "c"}});
  EXPECT_EQ(incomplete["ok"], false);
  EXPECT_NE(incomplete["error"].get<std::string>().find("incomplete (1 of 2 parts)"), std::string::npos) << incomplete;
  // Above a host file's size: refused part by part before it grows further.
  const std::string chunk(60 * 1024, '#');
  json r;
  for (std::size_t i = 0; i < 40; ++i) {
    r = call({{"op", "config_part"}, {"upload", "d"}, {"index", i}, {"count", 40}, {"text", chunk}});
    if (r["ok"] != true) break;
  }
  EXPECT_EQ(r["ok"], false);
  EXPECT_NE(r["error"].get<std::string>().find("larger than a host file may be"), std::string::npos) << r;
  // Bad ids and counts.
  for (const json& bad : {json{{"op", "config_part"}, {"upload", "../x"}, {"index", 0}, {"count", 1}, {"text", ""}},
                          json{{"op", "config_part"}, {"upload", "e"}, {"index", 0}, {"count", 0}, {"text", ""}},
                          json{{"op", "config_part"}, {"upload", "e"}, {"index", -1}, {"count", 2}, {"text", ""}},
                          json{{"op", "config_part"}, {"upload", "e"}, {"count", 2}, {"text", ""}}}) {
    EXPECT_EQ(call(bad)["ok"], false) << bad;
  }
  EXPECT_EQ(slurp(file), big);
}

TEST_F(ConfigServiceTest, MalformedRequestsAreAnsweredNotActedOn) {
  for (const char* text :
       {"{", "[]", R"({"op":"config_nothing"})", R"({"op":"config_save","file":3,"text":"x"})",
        R"({"op":"config_graph","dir":"/"})", R"({"op":"config_graph"})", R"({"op":"config_graph","live":false})",
        R"({"op":"config_graph","dir":"/","live":true})", R"({"op":"config_load"})"}) {
    const json r = json::parse(service_->handle(text));
    EXPECT_EQ(r["type"], "config") << text;
    EXPECT_EQ(r["ok"], false) << text;
    EXPECT_FALSE(r["error"].get<std::string>().empty()) << text;
  }
  EXPECT_EQ(slurp(served_ / "host.yaml"), kValid);
}

}  // namespace
}  // namespace rack::gui
