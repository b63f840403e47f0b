#include "host_tools/io/image_write.h"
#include "host_tools/io/png_error.h"

#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <set>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <png.h>

namespace camsim::io {
namespace {

constexpr int kMaxWriteDim = 1000000;

std::string Quoted(const std::string& path) { return "'" + path + "'"; }

// What kind of file st describes, for an error: "a directory", "a FIFO", ...
const char* KindOf(const struct stat& st) {
  if (S_ISDIR(st.st_mode)) return "a directory";
  if (S_ISFIFO(st.st_mode)) return "a FIFO (named pipe)";
  if (S_ISSOCK(st.st_mode)) return "a socket";
  if (S_ISCHR(st.st_mode)) return "a character device";
  if (S_ISBLK(st.st_mode)) return "a block device";
  return "not a regular file";
}

// A new file beside `path` for WriteAtomically: created with O_EXCL (mode
// 0666 less the umask, as fopen would), so it was no file before, whatever
// the directory holds. Empty on failure, with *error set.
std::string CreateTemporary(const std::string& path, std::string* error) {
  static std::atomic<unsigned> counter{0};
  for (int attempt = 0; attempt < 100; ++attempt) {
    const std::string tmp = path + ".tmp." + std::to_string(getpid()) + "." + std::to_string(counter++);
    const int fd = open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      close(fd);
      return tmp;
    }
    if (errno != EEXIST) {
      *error = "cannot write " + Quoted(path) + ": cannot create " + Quoted(tmp) + ": " + std::strerror(errno);
      return "";
    }
  }
  *error = "cannot write " + Quoted(path) + ": no free temporary name beside it";
  return "";
}

// The files RemoveTemporariesOnSignal's handler removes. A slot goes
// kFree -> kFilling (one thread owns it and copies the path) -> kSet, and
// back to kFree when unregistered; the handler takes kSet -> kTaken before
// it reads the path, so a slot being refilled is never read half-written.
// Only lock-free atomics, memcpy and unlink: all safe in a signal handler.
enum SlotState : int { kFree, kFilling, kSet, kTaken };
struct CleanupSlot {
  std::atomic<int> state{kFree};
  char path[PATH_MAX];
};
static_assert(std::atomic<int>::is_always_lock_free);
constexpr int kCleanupSlots = 64;
CleanupSlot g_cleanup[kCleanupSlots];

void RemoveTemporariesAndDie(int sig) {
  const int saved_errno = errno;
  for (CleanupSlot& slot : g_cleanup) {
    int expected = kSet;
    if (slot.state.compare_exchange_strong(expected, kTaken)) unlink(slot.path);
  }
  // The signal is blocked while its handler runs: raised again, it kills the
  // process (default action) as soon as the handler returns.
  struct sigaction dfl = {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  sigaction(sig, &dfl, nullptr);
  raise(sig);
  errno = saved_errno;
}

// Test hook: CAMSIM_TEST_HOOK_WRITE_PAUSE_MS=N makes every writer say so on
// standard error and wait N ms once its temporary file exists and is
// registered, so a test can kill the process there.
void TestHookPauseWrite(const std::string& tmp) {
  const char* ms = std::getenv("CAMSIM_TEST_HOOK_WRITE_PAUSE_MS");
  if (ms == nullptr) return;
  const long n = std::strtol(ms, nullptr, 10);
  if (n <= 0) return;
  std::fprintf(stderr, "camsim: test hook: pausing %ld ms in writing '%s'\n", n, tmp.c_str());
  struct timespec t = {static_cast<time_t>(n / 1000), (n % 1000) * 1000000L};
  while (nanosleep(&t, &t) != 0 && errno == EINTR) {
  }
}

}  // namespace

void RemoveTemporariesOnSignal() {
  // SIGXFSZ: a write past the file size limit.
  for (const int sig : {SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGXFSZ}) {
    struct sigaction old = {};
    if (sigaction(sig, nullptr, &old) != 0 || (old.sa_flags & SA_SIGINFO) != 0 || old.sa_handler != SIG_DFL)
      continue;
    struct sigaction sa = {};
    sa.sa_handler = RemoveTemporariesAndDie;
    sigfillset(&sa.sa_mask);  // no other signal interrupts the removal
    sigaction(sig, &sa, nullptr);
  }
}

RemovedOnSignal::RemovedOnSignal(const std::string& path) : slot_(-1) {
  if (path.size() >= sizeof(CleanupSlot::path)) return;
  for (int i = 0; i < kCleanupSlots; ++i) {
    int expected = kFree;
    if (!g_cleanup[i].state.compare_exchange_strong(expected, kFilling)) continue;
    std::memcpy(g_cleanup[i].path, path.c_str(), path.size() + 1);
    g_cleanup[i].state.store(kSet);
    slot_ = i;
    return;
  }
}

RemovedOnSignal::~RemovedOnSignal() {
  if (slot_ < 0) return;
  // kTaken: the handler is removing it, and the process is about to die.
  int expected = kSet;
  g_cleanup[slot_].state.compare_exchange_strong(expected, kFree);
}

std::string FollowSymlinks(const std::string& path, std::string* error) {
  std::string at = path;
  for (int hops = 0; hops < 40; ++hops) {
    struct stat st;
    if (lstat(at.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return at;
    std::string link(static_cast<size_t>(st.st_size > 0 ? st.st_size : 255) + 1, '\0');
    const ssize_t n = readlink(at.c_str(), link.data(), link.size());
    if (n < 0 || static_cast<size_t>(n) >= link.size()) {
      *error = "cannot write " + Quoted(path) + ": cannot read the symbolic link " + Quoted(at) +
               (n < 0 ? std::string(": ") + std::strerror(errno) : std::string(": it changed while read"));
      return "";
    }
    link.resize(static_cast<size_t>(n));
    // A relative target is relative to the link's directory.
    const size_t slash = at.find_last_of('/');
    at = link[0] == '/' || slash == std::string::npos ? link : at.substr(0, slash + 1) + link;
  }
  *error = "cannot write " + Quoted(path) + ": too many levels of symbolic links";
  return "";
}

bool WritableTarget(const std::string& path, std::string* target, std::string* error) {
  const std::string t = FollowSymlinks(path, error);
  if (t.empty()) return false;
  struct stat st;
  if (lstat(t.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    *error = "cannot write " + Quoted(path) + ": " + (t == path ? "it" : Quoted(t) + " (its link's target)") +
             " is " + KindOf(st) + "; only a regular file is replaced";
    return false;
  }
  *target = t;
  return true;
}

namespace {

// Runs write_tmp(tmp_path, error) and renames the result onto `path`; see the
// atomicity rule in image_write.h.
bool WriteAtomically(const std::string& path,
                     const std::function<bool(const std::string&, std::string*)>& write_tmp,
                     std::string* error) {
  std::string target;
  if (!WritableTarget(path, &target, error)) return false;
  const std::string tmp = CreateTemporary(target, error);
  if (tmp.empty()) return false;
  // (A signal in the few instructions since its creation leaves it.)
  const RemovedOnSignal on_signal(tmp);
  TestHookPauseWrite(tmp);
  std::error_code ec;
  bool ok = false;
  try {
    ok = write_tmp(tmp, error);
  } catch (const std::exception& e) {
    *error = "cannot write " + Quoted(path) + ": " + e.what();
  } catch (...) {
    *error = "cannot write " + Quoted(path) + ": unknown error";
  }
  if (ok && std::rename(tmp.c_str(), target.c_str()) != 0) {
    *error = "cannot write " + Quoted(path) + ": renaming " + Quoted(tmp) +
             " onto it failed: " + std::strerror(errno);
    ok = false;
  }
  if (!ok) std::filesystem::remove(tmp, ec);
  return ok;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

// WriteAtomically through a stdio stream: body(file, error) writes the bytes.
bool WriteViaFile(const std::string& path, const std::function<bool(std::FILE*, std::string*)>& body,
                  std::string* error) {
  return WriteAtomically(
      path,
      [&](const std::string& tmp, std::string* err) {
        std::unique_ptr<std::FILE, FileCloser> f(std::fopen(tmp.c_str(), "wb"));
        if (!f) {
          *err = "cannot write " + Quoted(path) + ": cannot create " + Quoted(tmp) + ": " +
                 std::strerror(errno);
          return false;
        }
        if (!body(f.get(), err)) return false;
        if (std::fclose(f.release()) != 0) {
          *err = "cannot write " + Quoted(path) + ": " + std::strerror(errno);
          return false;
        }
        return true;
      },
      error);
}

bool Put(std::FILE* f, const void* bytes, size_t n, const std::string& path, std::string* error) {
  if (std::fwrite(bytes, 1, n, f) == n) return true;
  *error = "cannot write " + Quoted(path) + ": " + std::strerror(errno);
  return false;
}

bool CheckImage(const std::string& path, const void* data, int width, int height, int channels,
                ptrdiff_t stride_samples, std::string* error) {
  if (data == nullptr) {
    *error = "cannot write " + Quoted(path) + ": no pixel data";
  } else if (channels < 1) {
    *error = "cannot write " + Quoted(path) + ": " + std::to_string(channels) + " channels";
  } else if (width < 1 || height < 1 || width > kMaxWriteDim || height > kMaxWriteDim) {
    *error = "cannot write " + Quoted(path) + ": bad size " + std::to_string(width) + "x" +
             std::to_string(height);
  } else if (stride_samples < ptrdiff_t{width} * channels) {
    *error = "cannot write " + Quoted(path) + ": stride " + std::to_string(stride_samples) +
             " is less than width x channels";
  } else {
    return true;
  }
  return false;
}

// OpenEXR's output through a stdio stream that remembers its first failure
// and then writes nothing more. Imf::OutputFile's own file stream buffered
// the last bytes until ~OutputFile, which swallows errors: a full disk went
// unnoticed. Nothing is thrown: some of ~OutputFile's calls are outside its
// try block.
class ExrFileStream : public Imf::OStream {
 public:
  ExrFileStream(std::FILE* f, const std::string& path) : Imf::OStream(path.c_str()), f_(f) {}

  void write(const char c[], int n) override {
    if (error_ == 0 && std::fwrite(c, 1, static_cast<size_t>(n), f_) != static_cast<size_t>(n)) Fail();
  }
  uint64_t tellp() override {
    const off_t pos = ftello(f_);
    if (pos >= 0) return static_cast<uint64_t>(pos);
    Fail();
    return 0;
  }
  void seekp(uint64_t pos) override {
    if (error_ == 0 && fseeko(f_, static_cast<off_t>(pos), SEEK_SET) != 0) Fail();
  }

  // errno of the first failure, 0 if none.
  int error() const { return error_; }

 private:
  void Fail() {
    if (error_ == 0) error_ = errno != 0 ? errno : EIO;
  }

  std::FILE* f_;
  int error_ = 0;
};

using detail::OnPngError;
using detail::OnPngWarning;
using detail::PngErrorText;

// Encodes the image into `f`. Because of setjmp/longjmp, no object with a
// destructor lives in this frame.
bool EncodePng(std::FILE* f, const void* data, int width, int height, int channels, int bit_depth,
               ptrdiff_t stride_samples, PngErrorText* err) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, err, OnPngError, OnPngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(err->text, sizeof err->text, "out of memory");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
               bit_depth, channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (bit_depth == 16 && std::endian::native == std::endian::little) png_set_swap(png);
  const size_t row_bytes = static_cast<size_t>(stride_samples) * static_cast<size_t>(bit_depth / 8);
  for (int y = 0; y < height; ++y) {
    png_write_row(png, static_cast<png_const_bytep>(data) + static_cast<size_t>(y) * row_bytes);
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

bool WritePnm16(const std::string& path, const uint16_t* data, int width, int height, int channels,
                ptrdiff_t stride_samples, int maxval, std::string* error) {
  if (channels != 1 && channels != 3) {
    *error = "cannot write " + Quoted(path) + ": PGM/PPM channels must be 1 or 3, not " + std::to_string(channels);
    return false;
  }
  if (!CheckImage(path, data, width, height, channels, stride_samples, error)) return false;
  if (maxval < 1 || maxval > 65535) {
    *error = "cannot write " + Quoted(path) + ": maxval " + std::to_string(maxval) +
             " is outside 1..65535";
    return false;
  }
  const int samples = width * channels;  // per row
  for (int y = 0; y < height; ++y) {
    for (int i = 0; i < samples; ++i) {
      const int v = data[y * stride_samples + i];
      if (v > maxval) {
        *error = "cannot write " + Quoted(path) + ": sample (" + std::to_string(i / channels) + "," +
                 std::to_string(y) + ")" + (channels == 1 ? "" : std::string(1, "RGB"[i % channels])) + " = " +
                 std::to_string(v) + " exceeds maxval " + std::to_string(maxval);
        return false;
      }
    }
  }
  return WriteViaFile(
      path,
      [&](std::FILE* f, std::string* err) {
        const std::string header = std::string(channels == 1 ? "P5" : "P6") + "\n" + std::to_string(width) + " " +
                                   std::to_string(height) + "\n" + std::to_string(maxval) + "\n";
        if (!Put(f, header.data(), header.size(), path, err)) return false;
        const size_t bytes = maxval < 256 ? 1 : 2;
        std::vector<unsigned char> row(static_cast<size_t>(samples) * bytes);
        for (int y = 0; y < height; ++y) {
          const uint16_t* src = data + y * stride_samples;
          for (int i = 0; i < samples; ++i) {
            if (bytes == 1) {
              row[i] = static_cast<unsigned char>(src[i]);
            } else {
              row[2 * i] = static_cast<unsigned char>(src[i] >> 8);
              row[2 * i + 1] = static_cast<unsigned char>(src[i] & 0xff);
            }
          }
          if (!Put(f, row.data(), row.size(), path, err)) return false;
        }
        return true;
      },
      error);
}

bool WritePng(const std::string& path, const void* data, int width, int height, int channels,
              int bit_depth, ptrdiff_t stride_samples, std::string* error) {
  if (channels != 1 && channels != 3) {
    *error = "cannot write " + Quoted(path) + ": PNG channels must be 1 or 3, not " +
             std::to_string(channels);
    return false;
  }
  if (bit_depth != 8 && bit_depth != 16) {
    *error = "cannot write " + Quoted(path) + ": PNG bit depth must be 8 or 16, not " +
             std::to_string(bit_depth);
    return false;
  }
  if (!CheckImage(path, data, width, height, channels, stride_samples, error)) return false;
  return WriteViaFile(
      path,
      [&](std::FILE* f, std::string* err) {
        PngErrorText png_error;
        if (EncodePng(f, data, width, height, channels, bit_depth, stride_samples, &png_error)) {
          return true;
        }
        *err = "cannot write " + Quoted(path) + ": libpng: " + png_error.text;
        return false;
      },
      error);
}

bool WriteRaw16(const std::string& path, const uint16_t* data, int width, int height, int channels,
                ptrdiff_t stride_samples, std::string* error) {
  if (!CheckImage(path, data, width, height, channels, stride_samples, error)) return false;
  return WriteViaFile(
      path,
      [&](std::FILE* f, std::string* err) {
        const int samples = width * channels;  // per row
        std::vector<unsigned char> row(static_cast<size_t>(samples) * 2);
        for (int y = 0; y < height; ++y) {
          const uint16_t* src = data + y * stride_samples;
          for (int i = 0; i < samples; ++i) {
            row[2 * i] = static_cast<unsigned char>(src[i] & 0xff);
            row[2 * i + 1] = static_cast<unsigned char>(src[i] >> 8);
          }
          if (!Put(f, row.data(), row.size(), path, err)) return false;
        }
        return true;
      },
      error);
}

bool WriteTextFile(const std::string& path, const std::string& text, std::string* error) {
  return WriteViaFile(
      path, [&](std::FILE* f, std::string* err) { return Put(f, text.data(), text.size(), path, err); },
      error);
}

bool WriteExr(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
              const std::vector<ExrAttribute>& attributes, std::string* error) {
  if (channels.empty()) {
    *error = "cannot write " + Quoted(path) + ": no channels";
    return false;
  }
  std::set<std::string> names;
  for (const ExrChannel& c : channels) {
    if (c.name.empty() || !names.insert(c.name).second) {
      *error = "cannot write " + Quoted(path) + ": channel name '" + c.name +
               "' is empty or repeated";
      return false;
    }
    if (!CheckImage(path, c.data, width, height, 1, c.stride_samples, error)) return false;
  }
  // Imf::Header::insert would replace a required attribute of the same type
  // (or throw for another type), and OpenEXR reads the multi-part, tiled
  // and deep ones into the file's structure: such a name is refused here.
  const Imf::Header required(1, 1);
  const std::set<std::string> structural = {"name", "type", "version", "chunkCount", "tiles"};
  names.clear();
  for (const ExrAttribute& a : attributes) {
    if (a.name.empty() || !names.insert(a.name).second || required.find(a.name) != required.end() ||
        structural.count(a.name) != 0) {
      *error = "cannot write " + Quoted(path) + ": attribute name '" + a.name +
               "' is empty, repeated or one OpenEXR sets";
      return false;
    }
  }
  return WriteViaFile(
      path,
      [&](std::FILE* f, std::string* err) {
        Imf::Header header(width, height);
        header.compression() = Imf::ZIP_COMPRESSION;
        for (const ExrAttribute& a : attributes) {
          if (a.is_text) header.insert(a.name, Imf::StringAttribute(a.text));
          else header.insert(a.name, Imf::DoubleAttribute(a.number));
        }
        Imf::FrameBuffer fb;
        for (const ExrChannel& c : channels) {
          // Both sample types are 4 bytes.
          const Imf::PixelType type = c.type == ExrSampleType::kUint ? Imf::UINT : Imf::FLOAT;
          header.channels().insert(c.name, Imf::Channel(type));
          fb.insert(c.name, Imf::Slice(type, static_cast<char*>(const_cast<void*>(c.data)), 4,
                                       static_cast<size_t>(c.stride_samples) * 4));
        }
        ExrFileStream stream(f, path);
        {
          // ~OutputFile writes the line-offset table and swallows any error.
          Imf::OutputFile file(stream, header);
          file.setFrameBuffer(fb);
          file.writePixels(height);
        }
        if (stream.error() == 0) return true;  // WriteViaFile checks fclose
        *err = "cannot write " + Quoted(path) + ": " + std::strerror(stream.error());
        return false;
      },
      error);
}

}  // namespace camsim::io
