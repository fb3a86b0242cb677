#include "firmware/session/h5.hpp"

#include <algorithm>
#include <stdexcept>

namespace haptic::firmware::h5 {

namespace {

// HDF5 prints its own error stacks by default; we throw with our message instead.
struct QuietErrors {
  QuietErrors() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }
};
const QuietErrors quiet_errors;

[[noreturn]] void fail(const std::string& what) { throw std::runtime_error("HDF5: " + what); }

void check(herr_t rc, const std::string& what) {
  if (rc < 0) fail(what);
}

hid_t mem_type(Type t) {
  switch (t) {
    case Type::kF64: return H5T_NATIVE_DOUBLE;
    case Type::kF32: return H5T_NATIVE_FLOAT;
    case Type::kI64: return H5T_NATIVE_INT64;
    case Type::kU64: return H5T_NATIVE_UINT64;
    case Type::kI32: return H5T_NATIVE_INT32;
    case Type::kU32: return H5T_NATIVE_UINT32;
    case Type::kU8: return H5T_NATIVE_UINT8;
  }
  return H5T_NATIVE_DOUBLE;
}

std::size_t native_bytes(Type t) { return H5Tget_size(mem_type(t)); }

hid_t file_type(Type t) {
  switch (t) {
    case Type::kF64: return H5T_IEEE_F64LE;
    case Type::kF32: return H5T_IEEE_F32LE;
    case Type::kI64: return H5T_STD_I64LE;
    case Type::kU64: return H5T_STD_U64LE;
    case Type::kI32: return H5T_STD_I32LE;
    case Type::kU32: return H5T_STD_U32LE;
    case Type::kU8: return H5T_STD_U8LE;
  }
  return H5T_IEEE_F64LE;
}

Id space(std::uint64_t rows, std::uint64_t cols) {
  const hsize_t dims[2] = {rows, cols};
  return Id(H5Screate_simple(cols ? 2 : 1, dims, nullptr), Id::Kind::kSpace, "dataspace");
}

Id str_type() {
  Id t(H5Tcopy(H5T_C_S1), Id::Kind::kType, "string type");
  check(H5Tset_size(t.get(), H5T_VARIABLE), "string type");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "string type");
  return t;
}

Id open_attr(hid_t obj, const std::string& name) { return Id(H5Aopen(obj, name.c_str(), H5P_DEFAULT), Id::Kind::kAttr, "attribute " + name); }

void scalar_attr(hid_t obj, const std::string& name, hid_t ftype, hid_t mtype, const void* v) {
  if (H5Aexists(obj, name.c_str()) > 0) check(H5Adelete(obj, name.c_str()), "attribute " + name);
  Id sp(H5Screate(H5S_SCALAR), Id::Kind::kSpace, "scalar space");
  Id a(H5Acreate2(obj, name.c_str(), ftype, sp.get(), H5P_DEFAULT, H5P_DEFAULT), Id::Kind::kAttr, "attribute " + name);
  check(H5Awrite(a.get(), mtype, v), "writing attribute " + name);
}

}  // namespace

Id::Id(hid_t id, Kind kind, const std::string& what) : id_(id), kind_(kind) {
  if (id < 0) fail(what);
}

Id& Id::operator=(Id&& o) noexcept {
  if (this != &o) {
    this->~Id();
    id_ = o.id_;
    kind_ = o.kind_;
    o.id_ = -1;
  }
  return *this;
}

Id::~Id() {
  if (id_ < 0) return;
  switch (kind_) {
    case Kind::kFile: H5Fclose(id_); break;
    case Kind::kGroup: H5Gclose(id_); break;
    case Kind::kDataset: H5Dclose(id_); break;
    case Kind::kSpace: H5Sclose(id_); break;
    case Kind::kType: H5Tclose(id_); break;
    case Kind::kAttr: H5Aclose(id_); break;
    case Kind::kPlist: H5Pclose(id_); break;
  }
  id_ = -1;
}

// A file written for as long as a session runs: the metadata cache (which holds the chunk index's
// nodes, and by default grows adaptively up to 32 MB) is fixed at kMetadataCacheBytes, so the
// writer's memory does not grow with the length of the log (in 10-minute recordings what grew was
// the chunk cache, Appendable; this bounds the index's share for longer logs).
Id create_file(const std::string& path) {
  Id fapl(H5Pcreate(H5P_FILE_ACCESS), Id::Kind::kPlist, "file access properties of " + path);
  H5AC_cache_config_t mdc;
  mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  check(H5Pget_mdc_config(fapl.get(), &mdc), "metadata cache of " + path);
  mdc.set_initial_size = true;
  mdc.initial_size = mdc.min_size = mdc.max_size = kMetadataCacheBytes;
  mdc.incr_mode = H5C_incr__off;
  mdc.flash_incr_mode = H5C_flash_incr__off;
  mdc.decr_mode = H5C_decr__off;
  check(H5Pset_mdc_config(fapl.get(), &mdc), "metadata cache of " + path);
  return Id(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), Id::Kind::kFile, "cannot create " + path);
}
Id open_file_read(const std::string& path) {
  return Id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), Id::Kind::kFile, "cannot open " + path + " (not an HDF5 file?)");
}
Id create_group(hid_t loc, const std::string& name) {
  return Id(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), Id::Kind::kGroup, "group " + name);
}
Id open_group(hid_t loc, const std::string& name) {
  return Id(H5Gopen2(loc, name.c_str(), H5P_DEFAULT), Id::Kind::kGroup, "no group " + name + " in the log");
}
bool exists(hid_t loc, const std::string& name) { return H5Lexists(loc, name.c_str(), H5P_DEFAULT) > 0; }
bool has_attr(hid_t obj, const std::string& name) { return H5Aexists(obj, name.c_str()) > 0; }
Id open_dataset(hid_t loc, const std::string& name) {
  return Id(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), Id::Kind::kDataset, "no dataset " + name + " in the log");
}
bool is_hdf5(const std::string& path) { return H5Fis_hdf5(path.c_str()) > 0; }

std::vector<std::string> dataset_paths(hid_t loc) {
  std::vector<std::string> out;
  const auto visit = [](hid_t g, const char* name, const H5L_info_t*, void* data) -> herr_t {
    const hid_t o = H5Oopen(g, name, H5P_DEFAULT);
    if (o < 0) return 0;  // a dangling link: not a dataset
    if (H5Iget_type(o) == H5I_DATASET) static_cast<std::vector<std::string>*>(data)->emplace_back(name);
    H5Oclose(o);
    return 0;
  };
  check(H5Lvisit(loc, H5_INDEX_NAME, H5_ITER_INC, visit, &out), "listing the datasets");
  return out;
}

std::string dtype_name(hid_t loc, const std::string& name) {
  Id ds = open_dataset(loc, name);
  Id t(H5Dget_type(ds.get()), Id::Kind::kType, "type of " + name);
  const std::string bits = std::to_string(8 * H5Tget_size(t.get()));
  switch (H5Tget_class(t.get())) {
    case H5T_FLOAT: return "float" + bits;
    case H5T_INTEGER: return (H5Tget_sign(t.get()) == H5T_SGN_NONE ? "uint" : "int") + bits;
    case H5T_STRING: return "string";
    default: return "other";
  }
}

void attr(hid_t obj, const std::string& name, double v) { scalar_attr(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &v); }
void attr(hid_t obj, const std::string& name, std::int64_t v) { scalar_attr(obj, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &v); }
void attr(hid_t obj, const std::string& name, const std::string& v) {
  Id t = str_type();
  const char* p = v.c_str();
  scalar_attr(obj, name, t.get(), t.get(), &p);
}

double attr_f64(hid_t obj, const std::string& name) {
  Id a = open_attr(obj, name);
  double v = 0;
  check(H5Aread(a.get(), H5T_NATIVE_DOUBLE, &v), "reading attribute " + name);
  return v;
}
std::int64_t attr_i64(hid_t obj, const std::string& name) {
  Id a = open_attr(obj, name);
  std::int64_t v = 0;
  check(H5Aread(a.get(), H5T_NATIVE_INT64, &v), "reading attribute " + name);
  return v;
}
std::string attr_str(hid_t obj, const std::string& name) {
  Id a = open_attr(obj, name);
  Id t = str_type();
  char* p = nullptr;
  check(H5Aread(a.get(), t.get(), &p), "reading attribute " + name);
  std::string s = p ? p : "";
  H5free_memory(p);
  return s;
}

void write(hid_t loc, const std::string& name, Type type, const void* data, std::uint64_t rows, std::uint64_t cols) {
  Id sp = space(rows, cols);
  Id ds(H5Dcreate2(loc, name.c_str(), file_type(type), sp.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), Id::Kind::kDataset, "dataset " + name);
  if (rows > 0) check(H5Dwrite(ds.get(), mem_type(type), H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "writing " + name);
}

std::vector<std::uint64_t> shape(hid_t loc, const std::string& name) {
  Id ds(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), Id::Kind::kDataset, "no dataset " + name + " in the log");
  Id sp(H5Dget_space(ds.get()), Id::Kind::kSpace, "space of " + name);
  hsize_t dims[2] = {0, 0};
  const int rank = H5Sget_simple_extent_dims(sp.get(), dims, nullptr);
  if (rank < 1 || rank > 2) fail(name + ": rank " + std::to_string(rank));
  return rank == 1 ? std::vector<std::uint64_t>{dims[0]} : std::vector<std::uint64_t>{dims[0], dims[1]};
}

void read_rows(hid_t loc, const std::string& name, Type type, void* out, std::uint64_t row0, std::uint64_t rows) {
  Id ds(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), Id::Kind::kDataset, "no dataset " + name + " in the log");
  Id fs(H5Dget_space(ds.get()), Id::Kind::kSpace, "space of " + name);
  hsize_t dims[2] = {0, 0};
  const int rank = H5Sget_simple_extent_dims(fs.get(), dims, nullptr);
  if (row0 + rows > dims[0]) fail(name + ": rows out of range");
  if (rows == 0) return;
  const hsize_t start[2] = {row0, 0}, count[2] = {rows, rank == 2 ? dims[1] : 1};
  check(H5Sselect_hyperslab(fs.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), "selecting " + name);
  Id ms = space(rows, rank == 2 ? dims[1] : 0);
  check(H5Dread(ds.get(), mem_type(type), ms.get(), fs.get(), H5P_DEFAULT, out), "reading " + name);
}

std::vector<double> read_f64(hid_t loc, const std::string& name) {
  const auto s = shape(loc, name);
  std::vector<double> v(s[0] * (s.size() == 2 ? s[1] : 1));
  read_rows(loc, name, Type::kF64, v.data(), 0, s[0]);
  return v;
}
std::vector<std::int64_t> read_i64(hid_t loc, const std::string& name) {
  const auto s = shape(loc, name);
  std::vector<std::int64_t> v(s[0] * (s.size() == 2 ? s[1] : 1));
  read_rows(loc, name, Type::kI64, v.data(), 0, s[0]);
  return v;
}

Appendable::Appendable(hid_t loc, const std::string& name, Type ftype, std::uint64_t cols, std::uint64_t chunk_rows, int deflate_level,
                       std::uint64_t ring_rows)
    : cols_(cols), ring_(ring_rows), name_(name) {
  if (ring_rows > 0) chunk_rows = std::min(chunk_rows, ring_rows);
  const hsize_t dims[2] = {0, cols}, maxdims[2] = {H5S_UNLIMITED, cols}, chunk[2] = {chunk_rows < 1 ? 1 : chunk_rows, cols};
  Id sp(H5Screate_simple(cols ? 2 : 1, dims, maxdims), Id::Kind::kSpace, "space of " + name);
  Id dcpl(H5Pcreate(H5P_DATASET_CREATE), Id::Kind::kPlist, "properties of " + name);
  check(H5Pset_chunk(dcpl.get(), cols ? 2 : 1, chunk), "chunking " + name);
  if (deflate_level > 0) {  // byte shuffle first: the bytes of slowly varying doubles compress far better grouped by position
    check(H5Pset_shuffle(dcpl.get()), "shuffle on " + name);
    check(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(deflate_level)), "deflate on " + name);
  }
  // The chunk cache holds the chunk being filled and one more (HDF5's default, 1 MB per dataset,
  // keeps up to 1 MB of written chunks of each of a session log's 20 datasets: memory that grew
  // for the first half hour of a recording); fully written chunks are evicted first (w0 = 1).
  const std::size_t chunk_bytes = static_cast<std::size_t>(chunk[0] * (cols ? cols : 1)) * H5Tget_size(file_type(ftype));
  Id dapl(H5Pcreate(H5P_DATASET_ACCESS), Id::Kind::kPlist, "access properties of " + name);
  check(H5Pset_chunk_cache(dapl.get(), 521, 2 * chunk_bytes, 1.0), "chunk cache of " + name);
  ds_ = Id(H5Dcreate2(loc, name.c_str(), file_type(ftype), sp.get(), H5P_DEFAULT, dcpl.get(), dapl.get()), Id::Kind::kDataset, "dataset " + name);
}

void Appendable::write_at(Type mtype, const void* data, std::uint64_t row0, std::uint64_t rows) {
  if (row0 + rows > rows_) {
    const hsize_t newdims[2] = {row0 + rows, cols_};
    check(H5Dset_extent(ds_.get(), newdims), "extending " + name_);
    rows_ = row0 + rows;
  }
  Id fs(H5Dget_space(ds_.get()), Id::Kind::kSpace, "space of " + name_);
  const hsize_t start[2] = {row0, 0}, count[2] = {rows, cols_ ? cols_ : 1};
  check(H5Sselect_hyperslab(fs.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), "selecting " + name_);
  Id ms = space(rows, cols_);
  check(H5Dwrite(ds_.get(), mem_type(mtype), ms.get(), fs.get(), H5P_DEFAULT, data), "appending to " + name_);
}

void Appendable::append(Type mtype, const void* data, std::uint64_t rows) {
  if (rows == 0) return;
  if (ring_ == 0) {
    write_at(mtype, data, rows_, rows);
    total_ += rows;
    return;
  }
  const std::size_t row_bytes = native_bytes(mtype) * (cols_ ? cols_ : 1);
  const auto* p = static_cast<const unsigned char*>(data);
  if (rows > ring_) {  // only the newest ring_ rows survive
    p += (rows - ring_) * row_bytes;
    total_ += rows - ring_;
    rows = ring_;
  }
  while (rows > 0) {  // at most two writes: up to the end of the ring, then from its start
    const std::uint64_t at = total_ % ring_, n = std::min(rows, ring_ - at);
    write_at(mtype, p, at, n);
    p += n * row_bytes;
    total_ += n;
    rows -= n;
  }
}

}  // namespace haptic::firmware::h5
