// The step's arrays: how they grow, and that the large ones are advised onto huge pages.
#include "dem/array_growth.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace millflow::dem {
namespace {

std::vector<std::uint32_t> counting(std::size_t n) {
  std::vector<std::uint32_t> v(n);
  std::iota(v.begin(), v.end(), 7u);
  return v;
}

TEST(ArrayGrowth, ReserveOnHugePagesKeepsTheElementsInOrder) {
  std::vector<std::uint32_t> v = counting(1000);
  reserve_on_huge_pages(v, 5000);
  EXPECT_GE(v.capacity(), 5000u);
  EXPECT_EQ(v, counting(1000));
}

TEST(ArrayGrowth, ResizeWithRoomGrowsBySixteenthBeyondWhatItMustHold) {
  std::vector<std::uint32_t> v = counting(100);
  resize_with_room(v, 1600);
  EXPECT_EQ(v.size(), 1600u);
  EXPECT_EQ(v.capacity(), 1700u);
  EXPECT_EQ(std::vector<std::uint32_t>(v.begin(), v.begin() + 100), counting(100));
  resize_with_room(v, 1650);  // within the room: no reallocation
  EXPECT_EQ(v.capacity(), 1700u);
}

TEST(ArrayGrowth, AssignOnHugePagesTakesExactlyWhatItMustHold) {
  std::vector<std::uint8_t> v(10, 3);
  assign_on_huge_pages(v, 4096, std::uint8_t{1});
  EXPECT_EQ(v.capacity(), 4096u);
  EXPECT_EQ(v, std::vector<std::uint8_t>(4096, 1));
  assign_on_huge_pages(v, 16, std::uint8_t{0});
  EXPECT_EQ(v, std::vector<std::uint8_t>(16, 0));
}

TEST(ArrayGrowth, SmallAndUnalignedRangesAreLeftAlone) {
  std::vector<double> v(10, 1.0);
  advise_huge_pages(v.data(), v.size() * sizeof(double));  // no whole 2 MiB page: nothing to ask
  advise_huge_pages(nullptr, 0);
  EXPECT_EQ(v, std::vector<double>(10, 1.0));
}

// The flags of the mapping that holds address, as /proc/self/smaps lists them ("hg": advised
// onto huge pages), or "" where no mapping holds it.
std::string mapping_flags(std::uintptr_t address) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool holds = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t begin = 0, end = 0;
    char dash = 0;
    std::istringstream header(line);
    if (header >> std::hex >> begin >> dash >> end && dash == '-') {
      holds = begin <= address && address < end;
    } else if (holds && line.starts_with("VmFlags:")) {
      return line.substr(8) + " ";
    }
  }
  return "";
}

TEST(ArrayGrowth, LargeArraysAreAdvisedOntoHugePages) {
  if (!std::filesystem::exists("/sys/kernel/mm/transparent_hugepage/enabled") ||
      !std::filesystem::exists("/proc/self/smaps")) {
    GTEST_SKIP() << "no transparent huge pages on this system";
  }
  std::vector<double> v;
  resize_with_room(v, std::size_t{8} << 20);  // 64 MiB
  const auto middle = reinterpret_cast<std::uintptr_t>(v.data() + v.size() / 2);
  EXPECT_NE(mapping_flags(middle).find(" hg "), std::string::npos) << mapping_flags(middle);
}

}  // namespace
}  // namespace millflow::dem
