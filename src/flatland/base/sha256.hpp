// SHA-256 (FIPS 180-4), for the provenance of results: a result names the scene file it was made
// from by the hash of its bytes, so a reader can tell whether a scene file is the one it came from.
#pragma once

#include <string>
#include <string_view>

namespace flatland {

// The SHA-256 digest of `bytes` as 64 lower-case hexadecimal digits.
std::string sha256_hex(std::string_view bytes);

}  // namespace flatland
