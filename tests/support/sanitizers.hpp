// Whether this test program is compiled for the sanitizer build (`make test-asan`): gcc defines
// __SANITIZE_ADDRESS__, clang answers __has_feature(address_sanitizer).
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define CSYMPNET_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CSYMPNET_UNDER_ASAN 1
#endif
#endif

namespace csympnet::testing {

#if defined(CSYMPNET_UNDER_ASAN)
inline constexpr bool kUnderSanitizers = true;
#else
inline constexpr bool kUnderSanitizers = false;
#endif

}  // namespace csympnet::testing
