#pragma once
// A small RAII layer over Debian's libhdf5 C API, just what the session log needs (firmware/
// session/log.hpp): files, groups, scalar attributes (numbers, UTF-8 strings), fixed datasets and
// row-appendable (chunked, unlimited first dimension) 1-D/2-D datasets, and reading them back.
// Every failure throws std::runtime_error naming the file and the object. None of it is RT-safe:
// it is used at start-up, on the recorder's writer thread and by replay tools.
#include <hdf5.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace haptic::firmware::h5 {

// One HDF5 identifier, closed with the right H5*close on destruction.
class Id {
 public:
  enum class Kind { kFile, kGroup, kDataset, kSpace, kType, kAttr, kPlist };
  Id() = default;
  Id(hid_t id, Kind kind, const std::string& what);  // throws when id < 0
  Id(Id&& o) noexcept : id_(o.id_), kind_(o.kind_) { o.id_ = -1; }
  Id& operator=(Id&& o) noexcept;
  Id(const Id&) = delete;
  Id& operator=(const Id&) = delete;
  ~Id();
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  Kind kind_ = Kind::kFile;
};

// Element types of the datasets we write (file type little-endian, memory type native).
enum class Type { kF64, kF32, kI64, kU64, kI32, kU32, kU8 };

// The metadata cache of a file create_file() makes: fixed, whatever the file's size.
inline constexpr std::size_t kMetadataCacheBytes = 2u << 20;
Id create_file(const std::string& path);   // truncates
Id open_file_read(const std::string& path);
Id create_group(hid_t loc, const std::string& name);
Id open_group(hid_t loc, const std::string& name);
bool exists(hid_t loc, const std::string& name);
Id open_dataset(hid_t loc, const std::string& name);
// Whether `path` is an HDF5 file (false for a missing or unreadable file too).
bool is_hdf5(const std::string& path);
// The paths of every dataset under `loc` ("ticks/force", ...), in name order.
std::vector<std::string> dataset_paths(hid_t loc);
// A dataset's element type as numpy spells it: "float64", "int32", "uint8", "string", ...
std::string dtype_name(hid_t loc, const std::string& name);

void attr(hid_t obj, const std::string& name, double v);
void attr(hid_t obj, const std::string& name, std::int64_t v);
void attr(hid_t obj, const std::string& name, const std::string& v);
double attr_f64(hid_t obj, const std::string& name);
std::int64_t attr_i64(hid_t obj, const std::string& name);
std::string attr_str(hid_t obj, const std::string& name);
bool has_attr(hid_t obj, const std::string& name);

// A whole dataset of `rows` x `cols` (cols = 0: 1-D of `rows`) written at once from native `data`
// of `type` (doubles stored as kF64, int64 as kI64, ...).
void write(hid_t loc, const std::string& name, Type type, const void* data, std::uint64_t rows, std::uint64_t cols = 0);
// Shape of a dataset: {rows} or {rows, cols}.
std::vector<std::uint64_t> shape(hid_t loc, const std::string& name);
// Rows [row0, row0 + rows) of a 1-D or 2-D dataset into `out` (native `type`; sized rows x cols).
void read_rows(hid_t loc, const std::string& name, Type type, void* out, std::uint64_t row0, std::uint64_t rows);
std::vector<double> read_f64(hid_t loc, const std::string& name);
std::vector<std::int64_t> read_i64(hid_t loc, const std::string& name);

// A dataset with an unlimited number of rows of `cols` values (cols = 0: scalars), stored as
// `file_type`, chunked `chunk_rows` rows at a time, optionally deflated (level 1..9, 0 = none).
// With ring_rows > 0 it is a ring: it grows to ring_rows rows, then each new row overwrites the
// oldest (row total % ring_rows), so the file stays bounded; next_row() is where the oldest row is
// once the ring is full (chronological order = rotate left by next_row()).
class Appendable {
 public:
  Appendable() = default;
  Appendable(hid_t loc, const std::string& name, Type file_type, std::uint64_t cols, std::uint64_t chunk_rows, int deflate_level = 0,
             std::uint64_t ring_rows = 0);
  // Appends `rows` rows of native `mem_type` values (HDF5 converts, e.g. double -> float32); in a
  // full ring they replace the oldest rows.
  void append(Type mem_type, const void* data, std::uint64_t rows);
  std::uint64_t rows() const { return rows_; }            // rows in the dataset
  std::uint64_t total() const { return total_; }          // rows ever appended
  std::uint64_t next_row() const { return ring_ ? total_ % ring_ : rows_; }
  hid_t id() const { return ds_.get(); }                  // the open dataset

 private:
  void write_at(Type mem_type, const void* data, std::uint64_t row0, std::uint64_t rows);
  Id ds_;
  std::uint64_t cols_ = 0, rows_ = 0, total_ = 0, ring_ = 0;
  std::string name_;
};

}  // namespace haptic::firmware::h5
