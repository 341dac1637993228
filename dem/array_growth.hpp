#pragma once
// How the arrays a step works on grow: by 1/16 beyond what they must hold, not by doubling.
// std::vector's push_back and resize double a full array, so a dense cell's per-pair and contact
// arrays held up to twice their bytes (the neighbour list of cement_load15: 55 bytes per candidate
// pair where 27 are used).
#include <cstddef>
#include <vector>

namespace millflow::dem {

// The free room kept beyond n elements.
inline std::size_t growth_room(std::size_t n) {
  return n / 16;
}

// v.resize(n), reallocating to n plus growth_room(n) when n exceeds the capacity.
template <class T>
void resize_with_room(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(n + growth_room(n));
  v.resize(n);
}

}  // namespace millflow::dem
