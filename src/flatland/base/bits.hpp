// The bits of one trivially copyable value as another type: std::bit_cast where the standard
// library has it, the same by memcpy where it does not (libc++ 14, the web build's).
#pragma once

#include <bit>
#include <cstring>
#include <type_traits>

namespace flatland {

#if defined(__cpp_lib_bit_cast)
using std::bit_cast;
#else
template <class To, class From>
To bit_cast(const From& from) noexcept {
  static_assert(sizeof(To) == sizeof(From) && std::is_trivially_copyable_v<To> && std::is_trivially_copyable_v<From>);
  To to;
  std::memcpy(&to, &from, sizeof to);
  return to;
}
#endif

}  // namespace flatland
