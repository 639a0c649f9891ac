// 64-bit FNV-1a: a small, fixed, platform-independent hash for cache keys and file checksums
// (not for security).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace csympnet {

inline constexpr std::uint64_t kFnvOffset = 14695981039346656037ULL;

// Continues the hash `h` over `bytes`.
constexpr std::uint64_t fnv1a64(std::string_view bytes, std::uint64_t h = kFnvOffset) {
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ULL;
  }
  return h;
}

// 16 lower-case hex digits.
std::string hex64(std::uint64_t h);

}  // namespace csympnet
