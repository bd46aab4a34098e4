#pragma once
// Writing output files so that a failed write is never silent and never replaces good data. A full disk, a
// file-size limit or a vanished folder shows up as an error at the write that hit it, naming the file and
// the system's reason ("No space left on device"), instead of at close time unseen. Whole files are written
// under a temporary name and renamed over the old one only once every byte is on disk, so the previous
// version (a good summary.json, the last checkpoint) stays when the new one cannot be written.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace cellfsi {

/// A file that could not be written; what() names the file and the system's reason.
class WriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "cannot write 'path': reason" as a WriteError.
[[noreturn]] inline void throw_write_error(const std::string& path, const std::string& reason) {
  throw WriteError("cannot write '" + path + "': " + reason);
}

/// Writes n bytes to fd, retrying short writes and interrupted calls. Returns 0, or the errno of the failure.
inline int write_all(int fd, const char* data, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (w == 0) return EIO;
    data += w;
    n -= static_cast<std::size_t>(w);
  }
  return 0;
}

/// Flushes the folder's entry list to disk, so that a rename in it survives a crash of the machine. Best
/// effort: some file systems refuse fsync on a folder, and the data itself is already on disk.
inline void sync_folder(const std::string& folder) {
  const int fd = ::open(folder.empty() ? "." : folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  (void)::fsync(fd);
  ::close(fd);
}

/// Renames a complete temporary file over path; on failure removes it and throws WriteError naming path.
/// `durable`: also flushes the folder's entry, so the new file survives a crash of the machine.
inline void replace_file(const std::string& tmp, const std::string& path, bool durable) {
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(tmp.c_str());
    throw_write_error(path, std::string("cannot rename '") + tmp + "' over it: " + std::strerror(err));
  }
  if (durable) sync_folder(std::filesystem::path(path).parent_path().string());
}

/// Writes text to path atomically: to path + ".tmp", checked at every write and at close (with fsync when
/// `durable`), then renamed over path. On any failure the temporary file is removed, path is left as it was
/// and WriteError is thrown.
inline void write_file_atomically(const std::string& path, const std::string& text, bool durable = true) {
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw_write_error(path, std::strerror(errno));
  int err = write_all(fd, text.data(), text.size());
  if (err == 0 && durable && ::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) err = errno;
  if (::close(fd) != 0 && err == 0 && errno != EINTR) err = errno;
  if (err != 0) {
    std::remove(tmp.c_str());
    throw_write_error(path, std::strerror(err));
  }
  replace_file(tmp, path, durable);
}

}  // namespace cellfsi
