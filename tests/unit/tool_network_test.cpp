// rack/client/host_file.h: the network a tool joins from a host file (libyaml, not
// yaml-cpp), read as rackd reads the same keys; every problem at its file:line:col.
#include <gtest/gtest.h>

#include <string>

#include "rack/client/host_file.h"

namespace rack {
namespace {

constexpr const char* kDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";

std::string errors_of(const ToolNetwork& n) {
  std::string out;
  for (const auto& e : n.errors) out += e.str() + "\n";
  return out;
}

TEST(ToolNetworkTest, DefaultWithoutNetworkKeys) {
  const auto n = read_tool_network_text("host: a\nsystem: 0\ncomponents: []\n", "a.yaml");
  EXPECT_TRUE(n.errors.empty()) << errors_of(n);
  EXPECT_EQ(n.url, kDefaultUrl);
  EXPECT_EQ(n.key_file, "");
}

TEST(ToolNetworkTest, LcmUrl) {
  const auto n = read_tool_network_text("host: a\nlcm_url: udpm://239.255.76.67:7700?ttl=1\n", "a.yaml");
  EXPECT_TRUE(n.errors.empty()) << errors_of(n);
  EXPECT_EQ(n.url, "udpm://239.255.76.67:7700?ttl=1");
}

TEST(ToolNetworkTest, FirstTimsNetworkWinsOverLcmUrl) {
  const auto n = read_tool_network_text(
      "lcm_url: udpm://239.255.76.67:7700\n"
      "tims:\n"
      "  networks:\n"
      "    - {name: robot, url: \"udpm://239.255.76.68:7701?ttl=0\", key_file: /etc/rack/robot.key}\n"
      "    - name: fleet\n"
      "      url: udpm://239.255.76.69:7702?ttl=1\n",
      "a.yaml");
  EXPECT_TRUE(n.errors.empty()) << errors_of(n);
  EXPECT_EQ(n.url, "udpm://239.255.76.68:7701?ttl=0");
  EXPECT_EQ(n.key_file, "/etc/rack/robot.key");
}

TEST(ToolNetworkTest, AnchorsAndAliasesResolve) {
  const auto n = read_tool_network_text(
      "defaults: &net {url: udpm://239.255.76.67:7705, key_file: k.key}\n"
      "tims:\n  networks: [*net]\n",
      "a.yaml");
  EXPECT_TRUE(n.errors.empty()) << errors_of(n);
  EXPECT_EQ(n.url, "udpm://239.255.76.67:7705");
  EXPECT_EQ(n.key_file, "k.key");
}

TEST(ToolNetworkTest, SyntaxErrorHasItsLine) {
  const auto n = read_tool_network_text("host: a\nlcm_url: [unclosed\nsystem: 0\n", "bad.yaml");
  ASSERT_EQ(n.errors.size(), 1u);
  EXPECT_EQ(n.errors[0].file, "bad.yaml");
  EXPECT_GE(n.errors[0].line, 2);
  EXPECT_NE(n.errors[0].message.find("YAML syntax"), std::string::npos) << errors_of(n);
}

TEST(ToolNetworkTest, RefusedShapesSayWhereAndWhy) {
  struct Case {
    const char* text;
    int line;
    const char* message;
  };
  const Case cases[] = {
      {"- a\n- b\n", 1, "a host file is a map"},
      {"", 0, "a host file is a map"},
      {"host: a\nlcm_url: {x: 1}\n", 2, "'lcm_url' must be a string"},
      {"tims:\n  networks: 3\n", 2, "'networks' must be a non-empty list"},
      {"tims:\n  networks: []\n", 2, "'networks' must be a non-empty list"},
      {"tims:\n  networks:\n    - name: robot\n", 3, "the first network has no 'url'"},
      {"tims:\n  networks:\n    - url: [a]\n", 3, "'url' must be a string"},
      {"tims:\n  networks: [*nothing]\n", 2, "names no anchor"},
      // An empty or malformed URL is refused at its line as rackd refuses it (fuzz_tool_network
      // found `lcm_url:` with no value answered with no URL and no error).
      {"lcm_url:\nhost: a\n", 1, "'lcm_url': an LCM URL must not be empty"},
      {"lcm_url: udpm://239.255.76.67:99999\n", 1, "is not a number 1..65535"},
      {"tims:\n  networks:\n    - url: udpm://10.0.0.1:7667\n", 3, "is not a multicast address"},
  };
  for (const auto& c : cases) {
    const auto n = read_tool_network_text(c.text, "t.yaml");
    ASSERT_FALSE(n.errors.empty()) << c.text;
    EXPECT_EQ(n.errors[0].line, c.line) << c.text << "\n" << errors_of(n);
    EXPECT_NE(n.errors[0].message.find(c.message), std::string::npos) << c.text << "\n" << errors_of(n);
  }
}

TEST(ToolNetworkTest, NestingIsBounded) {
  std::string deep;
  for (int i = 0; i < 100; ++i) deep += "[";
  const auto n = read_tool_network_text("a: " + deep + "\n", "deep.yaml");
  ASSERT_FALSE(n.errors.empty());
  EXPECT_NE(n.errors[0].message.find("nested deeper than 32"), std::string::npos) << errors_of(n);
}

TEST(ToolNetworkTest, OnlyTheFirstDocumentIsRead) {
  const auto n = read_tool_network_text("lcm_url: udpm://239.255.76.67:7710\n---\nlcm_url: [\n", "two.yaml");
  EXPECT_TRUE(n.errors.empty()) << errors_of(n);
  EXPECT_EQ(n.url, "udpm://239.255.76.67:7710");
}

TEST(ToolNetworkTest, UnreadableFilesAreRefusedByPath) {
  const auto missing = read_tool_network("/nonexistent/host.yaml");
  ASSERT_EQ(missing.errors.size(), 1u);
  EXPECT_EQ(missing.errors[0].file, "/nonexistent/host.yaml");
  EXPECT_NE(missing.errors[0].message.find("cannot read the host file"), std::string::npos);
  const auto dir = read_tool_network("/tmp");
  ASSERT_EQ(dir.errors.size(), 1u);
  EXPECT_NE(dir.errors[0].message.find("a directory"), std::string::npos) << errors_of(dir);
}

}  // namespace
}  // namespace rack
