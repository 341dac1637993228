#pragma once
// How the arrays a step works on grow: by 1/16 beyond what they must hold, not by doubling.
// std::vector's push_back and resize double a full array, so a dense cell's per-pair and contact
// arrays held up to twice their bytes (the neighbour list of cement_load15: 55 bytes per candidate
// pair where 27 are used). And where they live: the large ones advised onto huge pages, where the
// system offers them (docs/benchmarks.md, "The pair pass asks for its particles ahead"). The
// advice takes only on memory not touched before: a buffer the C library carves from memory it
// handed out earlier keeps its small pages (on the campaign's fine cell at load 1, 4 MiB of
// 82 MiB were on huge pages; all of them there did not change its speed measurably:
// docs/benchmarks.md, "Where the campaign's fine cells spend their step").
#include <cstddef>
#include <iterator>
#include <vector>

namespace millflow::dem {

// The free room kept beyond n elements.
inline std::size_t growth_room(std::size_t n) {
  return n / 16;
}

// Asks the kernel to back the whole 2 MiB pages within [data, data + bytes) with transparent
// huge pages (Linux's madvise(MADV_HUGEPAGE), where the system leaves that choice to the program;
// nothing elsewhere). A dense cell's arrays (100 MB for 114,000 particles) outrun the address
// cache's reach on 4 KiB pages. Pages touched before the advice stay small until the kernel's
// background collapse, if ever: hence the callers below advise a buffer before filling it.
void advise_huge_pages(const void* data, std::size_t bytes);

// Moves v into a new buffer of the given capacity, advised as above before anything touches it
// (std::vector::reserve would copy the elements first).
template <class T>
void reserve_on_huge_pages(std::vector<T>& v, std::size_t capacity) {
  std::vector<T> grown;
  grown.reserve(capacity);
  advise_huge_pages(grown.data(), capacity * sizeof(T));
  grown.insert(grown.end(), std::make_move_iterator(v.begin()), std::make_move_iterator(v.end()));
  v = std::move(grown);
}

// v.resize(n), reallocating to n plus growth_room(n) when n exceeds the capacity.
template <class T>
void resize_with_room(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) reserve_on_huge_pages(v, n + growth_room(n));
  v.resize(n);
}

// v.assign(n, value), reallocating to exactly n when n exceeds the capacity.
template <class T>
void assign_on_huge_pages(std::vector<T>& v, std::size_t n, const T& value) {
  if (n > v.capacity()) {
    v.clear();
    reserve_on_huge_pages(v, n);
  }
  v.assign(n, value);
}

}  // namespace millflow::dem
