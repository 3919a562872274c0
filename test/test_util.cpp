// The utilities against independent truths: util::printable against byte strings whose text form is
// known (what goes out in a message is text, whatever came in); util::read_regular_file against
// special files that would block or never end, and a file of known size.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>
#include <string>

#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/util/files.h"
#include "hydrojet_control/util/text.h"

using hydrojet::util::printable;

TEST(Printable, KeepsTextAndEscapesEverythingElse) {
  EXPECT_EQ(printable("plain text, 3 numbers: 1 2 3"), "plain text, 3 numbers: 1 2 3");
  EXPECT_EQ(printable("line one\n\tline two"), "line one\n\tline two");
  EXPECT_EQ(printable("\xcf\x91 \xcf\x86 \xe2\x80\x94 \xf0\x9f\x98\x80"),
            "\xcf\x91 \xcf\x86 \xe2\x80\x94 \xf0\x9f\x98\x80");
  EXPECT_EQ(printable(std::string("a\0b", 3)), "a\\x00b");
  EXPECT_EQ(printable("\x01\x7f\x1b[A"), "\\x01\\x7f\\x1b[A");
  EXPECT_EQ(printable("\xff\xfe"), "\\xff\\xfe");                    // never UTF-8
  EXPECT_EQ(printable("\xc0\xaf"), "\\xc0\\xaf");                    // an overlong '/'
  EXPECT_EQ(printable("\xed\xa0\x80"), "\\xed\\xa0\\x80");           // a UTF-16 surrogate
  EXPECT_EQ(printable("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");  // above U+10FFFF
  EXPECT_EQ(printable("\xe2\x80"), "\\xe2\\x80");                    // cut short
  EXPECT_EQ(printable("ok\xe2\x80z"), "ok\\xe2\\x80z");
}

TEST(Printable, IsBoundedAndCutsBetweenCharacters) {
  EXPECT_EQ(printable(std::string(10, 'x'), 10), std::string(10, 'x'));
  EXPECT_EQ(printable(std::string(11, 'x'), 10), std::string(10, 'x') + "...");
  EXPECT_EQ(printable(std::string(1 << 20, '\xff'), 10), "\\xff\\xff...");  // never half an escape
  EXPECT_EQ(printable("aaaaaaaaa\xcf\x91", 10), "aaaaaaaaa...");            // never half a character
  EXPECT_LE(printable(std::string(1 << 20, 'y')).size(), 1024u + 3u);
}

TEST(ReadRegularFile, ReadsARegularFileWhole) {
  const std::string path = ::testing::TempDir() + "util_file.txt";
  std::ofstream(path) << std::string(100000, 'a') << "end";
  std::string text;
  EXPECT_EQ(hydrojet::util::read_regular_file(path, &text), "");
  EXPECT_EQ(text.size(), 100003u);
  EXPECT_EQ(text.substr(text.size() - 3), "end");
  EXPECT_EQ(hydrojet::util::read_regular_file(path, &text, 100002), "100003 bytes, more than the limit of 100002");
  EXPECT_EQ(text, "");
}

TEST(ReadRegularFile, RefusesWhatWouldBlockOrNeverEnd) {
  const std::string fifo = ::testing::TempDir() + "util_fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string text = "x";
  for (const std::string& path : {fifo, std::string("/dev/null"), std::string("/dev/zero"), ::testing::TempDir()}) {
    EXPECT_EQ(hydrojet::util::read_regular_file(path, &text), "not a regular file") << path;
    EXPECT_EQ(text, "");
  }
  EXPECT_EQ(hydrojet::util::read_regular_file("/nonexistent/file", &text).rfind("cannot be read (", 0), 0u);
  ::unlink(fifo.c_str());
  // A scene named /dev/zero is refused, not read into memory for ever.
  try {
    hydrojet::config::load_scene("/dev/zero");
    ADD_FAILURE() << "loaded /dev/zero";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
}
