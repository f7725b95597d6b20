#include "process/io/json_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <vector>

namespace rig {

Result<nlohmann::json> ReadJsonObjectFile(const std::string& path, uint64_t max_bytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int e = errno;
    return MakeError(e == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo, path, "cannot open: {}",
                     std::strerror(e));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return MakeError(ErrorCode::kInvalidInput, path, "not a regular file");
  }
  if (static_cast<uint64_t>(st.st_size) > max_bytes) {
    ::close(fd);
    return MakeError(ErrorCode::kInvalidInput, path, "{} bytes: larger than the {} a JSON file may hold",
                     st.st_size, max_bytes);
  }
  std::string text(static_cast<size_t>(st.st_size), '\0');
  size_t got = 0;
  while (got < text.size()) {
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kInvalidInput, path, "not JSON: {}", e.what());
  }
  if (!j.is_object()) return MakeError(ErrorCode::kInvalidInput, path, "not a JSON object");
  return j;
}

Result<int> JsonIntegerIn(const nlohmann::json& v, int lo, int hi, const std::string& path,
                          const std::string& field) {
  if (!v.is_number_integer() || v.get<int64_t>() < lo || v.get<int64_t>() > hi)
    return MakeError(ErrorCode::kInvalidInput, path, "{}: {} is not an integer in {}..{}", field,
                     v.dump(), lo, hi);
  return static_cast<int>(v.get<int64_t>());
}

Result<double> JsonNumber(const nlohmann::json& v, const std::string& path, const std::string& field) {
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    return MakeError(ErrorCode::kInvalidInput, path, "{}: {} is not a finite number", field, v.dump());
  return v.get<double>();
}

}  // namespace rig
