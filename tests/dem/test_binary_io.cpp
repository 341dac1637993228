#include "dem/binary_io.hpp"
#include "util/sha256.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

namespace millflow::dem {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kMagic = "MFTEST01";

struct Sample {
  std::int32_t id;
  double value;
};

class BinaryFile : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("millflow_binary_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::string slurp(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  static void dump(const fs::path& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  }

  fs::path dir_;
};

std::string payload_of_every_kind() {
  BinaryWriter w;
  w.put<std::int32_t>(-7);
  w.put(3.25);
  w.put(Sample{42, -1.5});
  const std::vector<double> values{1.0, 2.5, -3.75};
  w.put_span(std::span<const double>(values));
  w.put_span(std::span<const std::int64_t>());
  w.put_string("shear cell");
  w.put_string("");
  w.put<std::uint8_t>(255);
  return w.bytes();
}

TEST(BinaryWriterReader, RoundTripOfPodsVectorsAndStrings) {
  const std::string bytes = payload_of_every_kind();
  BinaryReader r(bytes);
  EXPECT_EQ(r.get<std::int32_t>(), -7);
  EXPECT_EQ(r.get<double>(), 3.25);
  const auto s = r.get<Sample>();
  EXPECT_EQ(s.id, 42);
  EXPECT_EQ(s.value, -1.5);
  EXPECT_EQ(r.get_vector<double>(), (std::vector<double>{1.0, 2.5, -3.75}));
  EXPECT_TRUE(r.get_vector<std::int64_t>().empty());
  EXPECT_EQ(r.get_string(), "shear cell");
  EXPECT_EQ(r.get_string(), "");
  EXPECT_FALSE(r.at_end());
  EXPECT_EQ(r.get<std::uint8_t>(), 255);
  EXPECT_TRUE(r.at_end());
}

TEST(BinaryWriterReader, EncodingIsLittleEndianWithCountPrefixes) {
  BinaryWriter w;
  w.put<std::uint32_t>(0x01020304u);
  w.put_string("ab");
  const std::string expected(
      "\x04\x03\x02\x01"
      "\x02\0\0\0\0\0\0\0"
      "ab",
      14);
  EXPECT_EQ(w.bytes(), expected);
}

TEST(BinaryWriterReader, OverrunThrowsWithThePosition) {
  BinaryWriter w;
  w.put<std::int32_t>(1);
  BinaryReader r(w.bytes());
  r.get<std::int32_t>();
  try {
    r.get<double>();
    FAIL() << "no exception";
  } catch (const CorruptData& e) {
    EXPECT_STREQ(e.what(),
                 "binary data truncated at byte 4: reading a value needs 8 bytes, only "
                 "0 remain");
  }
}

TEST(BinaryWriterReader, HugeCountsAreRejectedBeforeAllocating) {
  BinaryWriter w;
  w.put<std::uint64_t>(~std::uint64_t{0});
  w.put<double>(1.0);
  BinaryReader vector_reader(w.bytes());
  EXPECT_THROW(vector_reader.get_vector<double>(), CorruptData);
  BinaryReader string_reader(w.bytes());
  EXPECT_THROW(string_reader.get_string(), CorruptData);
}

TEST(BinaryWriterReader, EveryTruncatedPayloadThrows) {
  const std::string bytes = payload_of_every_kind();
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    BinaryReader r(std::string_view(bytes).substr(0, length));
    EXPECT_THROW(
        {
          r.get<std::int32_t>();
          r.get<double>();
          r.get<Sample>();
          r.get_vector<double>();
          r.get_vector<std::int64_t>();
          r.get_string();
          r.get_string();
          r.get<std::uint8_t>();
        },
        CorruptData)
        << "length " << length;
  }
}

TEST(Sha256, KnownVectors) {
  EXPECT_EQ(util::sha256_hex(""),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(util::sha256_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST_F(BinaryFile, RoundTripWithVersion) {
  const fs::path path = dir_ / "sample.bin";
  const std::string payload = payload_of_every_kind();
  write_checksummed_file(path, kMagic, 3, payload);
  std::uint32_t version = 0;
  EXPECT_EQ(read_checksummed_file(path, kMagic, 5, &version), payload);
  EXPECT_EQ(version, 3u);
}

TEST_F(BinaryFile, LayoutIsMagicVersionSizePayloadChecksum) {
  const fs::path path = dir_ / "layout.bin";
  write_checksummed_file(path, kMagic, 0x0A0B0C0Du, "xyz");
  const std::string bytes = slurp(path);
  ASSERT_EQ(bytes.size(), 8u + 4u + 8u + 3u + 32u);
  EXPECT_EQ(bytes.substr(0, 20), std::string("MFTEST01\x0D\x0C\x0B\x0A\x03\0\0\0\0\0\0\0", 20));
  EXPECT_EQ(bytes.substr(20, 3), "xyz");
  std::string stored_hex;
  for (unsigned char c : bytes.substr(23)) stored_hex += fmt::format("{:02x}", c);
  EXPECT_EQ(stored_hex, util::sha256_hex(bytes.substr(0, 23)));
}

TEST_F(BinaryFile, TruncationAtEveryLengthIsRejected) {
  const fs::path good = dir_ / "good.bin", cut = dir_ / "cut.bin";
  write_checksummed_file(good, kMagic, 1, payload_of_every_kind());
  const std::string bytes = slurp(good);
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    dump(cut, bytes.substr(0, length));
    EXPECT_THROW(read_checksummed_file(cut, kMagic, 1), CorruptData) << "length " << length;
  }
}

TEST_F(BinaryFile, AFlippedBitAtEveryByteIsDetected) {
  const fs::path good = dir_ / "good.bin", bad = dir_ / "bad.bin";
  write_checksummed_file(good, kMagic, 1, payload_of_every_kind());
  const std::string bytes = slurp(good);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::string flipped = bytes;
    flipped[i] = static_cast<char>(flipped[i] ^ (1 << (i % 8)));
    dump(bad, flipped);
    EXPECT_THROW(read_checksummed_file(bad, kMagic, 1), CorruptData) << "byte " << i;
  }
}

TEST_F(BinaryFile, TrailingBytesAreASizeMismatch) {
  const fs::path path = dir_ / "long.bin";
  write_checksummed_file(path, kMagic, 1, "payload");
  dump(path, slurp(path) + "!");
  try {
    read_checksummed_file(path, kMagic, 1);
    FAIL() << "no exception";
  } catch (const CorruptData& e) {
    EXPECT_NE(std::string(e.what()).find("size mismatch"), std::string::npos) << e.what();
  }
}

TEST_F(BinaryFile, NewerVersionIsRefusedWithTheExactMessage) {
  const fs::path path = dir_ / "future.bin";
  write_checksummed_file(path, kMagic, 7, "payload");
  try {
    read_checksummed_file(path, kMagic, 6);
    FAIL() << "no exception";
  } catch (const CorruptData& e) {
    EXPECT_EQ(std::string(e.what()), "'" + path.string() +
                                         "' was written by a newer millflow: version 7, this "
                                         "build reads up to 6");
  }
}

TEST_F(BinaryFile, WrongMagicNamesTheExpectedKind) {
  const fs::path path = dir_ / "other.bin";
  write_checksummed_file(path, "MFOTHER1", 1, "payload");
  try {
    read_checksummed_file(path, kMagic, 1);
    FAIL() << "no exception";
  } catch (const CorruptData& e) {
    EXPECT_EQ(std::string(e.what()), "'" + path.string() + "' is not a MFTEST01 file");
  }
}

TEST_F(BinaryFile, MissingFileIsCorruptData) {
  EXPECT_THROW(read_checksummed_file(dir_ / "absent.bin", kMagic, 1), CorruptData);
}

TEST_F(BinaryFile, MagicMustBeEightBytes) {
  EXPECT_THROW(write_checksummed_file(dir_ / "x.bin", "SHORT", 1, ""), std::invalid_argument);
  EXPECT_THROW(read_checksummed_file(dir_ / "x.bin", "TOO_LONG_", 1), std::invalid_argument);
}

TEST_F(BinaryFile, RewriteReplacesTheFileAndLeavesNoTemporary) {
  const fs::path path = dir_ / "state.bin";
  write_checksummed_file(path, kMagic, 1, "first");
  write_checksummed_file(path, kMagic, 1, "second, longer");
  EXPECT_EQ(read_checksummed_file(path, kMagic, 1), "second, longer");
  std::vector<fs::path> entries;
  for (const auto& entry : fs::directory_iterator(dir_)) entries.push_back(entry.path());
  EXPECT_EQ(entries, std::vector<fs::path>{path});
}

}  // namespace
}  // namespace millflow::dem
