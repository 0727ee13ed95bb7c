// hybridbrdf — the safetensors container of model files: the file checked for what it is,
// the header length and text, the header parsed as strictly as serde parses it, the data
// section's layout, then exactly the tensor bytes the header declares. The metadata it
// returns is checked against the model contract by model_validate.cpp.
#include "model_container.hpp"

#include <algorithm>
#include <fstream>
#include <limits>
#include <set>
#include <tuple>
#include <sstream>

#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "hybridbrdf/model.hpp"

namespace hbrdf::model_file {
namespace {

using json = nlohmann::json;
using spec::kMaxHeaderBytes;

// A tensor's entry in the header, before its data is read.
struct Entry {
    std::string name;
    std::vector<std::int64_t> shape;
    std::uint64_t start, end;
};

// What the file is, before opening it (python/hybridbrdf/inputs.py, the same words): opening a
// FIFO blocks until a writer comes, and a device such as /dev/zero never ends.
void check_file_kind(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return;  // opening it reports what is wrong
    if (S_ISDIR(st.st_mode)) throw ModelFileError(path, "is a folder, not a model file");
    if (S_ISFIFO(st.st_mode)) throw ModelFileError(path, "is a FIFO, not a regular file");
    if (S_ISCHR(st.st_mode)) throw ModelFileError(path, "is a character device, not a regular file");
    if (S_ISBLK(st.st_mode)) throw ModelFileError(path, "is a block device, not a regular file");
    if (S_ISSOCK(st.st_mode)) throw ModelFileError(path, "is a socket, not a regular file");
    if (!S_ISREG(st.st_mode)) throw ModelFileError(path, "is not a regular file");
    // The contract bounds a model's size (spec::kMaxDataBytes); the Python loader refuses a
    // longer file with these words too (inputs.check_input_file).
    const std::uint64_t limit = 8 + kMaxHeaderBytes + spec::kMaxDataBytes;
    if (static_cast<std::uint64_t>(st.st_size) > limit)
        throw ModelFileError(path, "model file too long: " + std::to_string(st.st_size) +
                                       " bytes (a model file is at most " + std::to_string(limit) + " bytes)");
}

// The file's size, from a stream opened at its end.
std::uint64_t file_size(const std::string& path, std::ifstream& in) {
    const std::streamoff file_size = in.tellg();
    if (file_size < 0) throw ModelFileError(path, "not a regular file");
    const std::uint64_t size = static_cast<std::uint64_t>(file_size);
    if (size < 8)
        throw ModelFileError(path, "truncated: " + std::to_string(size) + " bytes, not even a safetensors header length");
    return size;
}

// The header's text: its little-endian 64-bit length checked against the contract's bound and
// the file's size before anything is allocated (a damaged length must not size a buffer).
std::string read_header_text(const std::string& path, std::ifstream& in, std::uint64_t size) {
    unsigned char head[8];
    in.seekg(0);
    in.read(reinterpret_cast<char*>(head), 8);
    std::uint64_t hlen = 0;
    for (int i = 7; i >= 0; --i) hlen = (hlen << 8) | head[i];
    if (hlen > kMaxHeaderBytes || 8 + hlen > size)
        throw ModelFileError(path, "not a safetensors file or truncated (header length " + std::to_string(hlen) +
                                       ", file " + std::to_string(size) + " bytes)");
    std::string text(static_cast<std::size_t>(hlen), '\0');
    if (!in.read(text.data(), static_cast<std::streamsize>(hlen)))
        throw ModelFileError(path, "cannot read the " + std::to_string(hlen) + "-byte header (changed while reading?)");
    return text;
}

// The safetensors header text as the Python loader's parser (serde_json, in the safetensors
// package) reads it, where nlohmann-json is more lenient: it skips a UTF-8 byte-order mark and
// stops at a NUL. Raw control characters are invalid anywhere in JSON but for the whitespace
// \t \n \r between tokens, so refusing them all is exact. Empty when acceptable.
std::string header_text_problem(const std::string& text) {
    if (text.size() >= 3 && static_cast<unsigned char>(text[0]) == 0xEF &&
        static_cast<unsigned char>(text[1]) == 0xBB && static_cast<unsigned char>(text[2]) == 0xBF)
        return "the header starts with a UTF-8 byte-order mark";
    for (std::size_t i = 0; i < text.size(); ++i) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if (c < 0x20 && c != '\t' && c != '\n' && c != '\r')
            return "control character " + std::to_string(int(c)) + " at header byte " + std::to_string(i);
    }
    return {};
}

// The header parsed, and refused where serde would refuse it though nlohmann-json does not.
json parse_header(const std::string& path, const std::string& text) {
    // serde refuses a repeated field of a struct: "__metadata__" at the top, and "dtype", "shape"
    // or "data_offsets" in a tensor's entry (repeated tensor names and metadata keys are a map's,
    // the last one wins, in both parsers). Noted during the parse, reported after it.
    std::string repeated;
    std::set<std::string> entry_fields;
    bool top_metadata = false, in_entry = false;
    const json::parser_callback_t note = [&](int depth, json::parse_event_t event, json& parsed) {
        if (event == json::parse_event_t::object_start && depth == 1) entry_fields.clear();
        if (event == json::parse_event_t::key && parsed.is_string()) {
            const std::string& k = parsed.get_ref<const std::string&>();
            if (depth == 1) {
                in_entry = k != "__metadata__";
                if (!in_entry && top_metadata && repeated.empty()) repeated = "__metadata__";
                top_metadata = top_metadata || !in_entry;
            } else if (depth == 2 && in_entry && (k == "dtype" || k == "shape" || k == "data_offsets") &&
                       !entry_fields.insert(k).second && repeated.empty()) {
                repeated = k;
            }
        }
        return true;
    };
    json header;
    try {
        header = json::parse(text, note);
    } catch (const json::exception& e) {
        throw ModelFileError(path, std::string("safetensors header is not valid JSON (") + e.what() + ")");
    }
    // After the parse, so that text nlohmann-json refuses keeps its message (which byte, where).
    if (const std::string problem = header_text_problem(text); !problem.empty())
        throw ModelFileError(path, "not a valid safetensors file (" + problem + ")");
    if (!repeated.empty())
        throw ModelFileError(path, "not a valid safetensors file (the header repeats the field '" + repeated + "')");
    if (!header.is_object()) throw ModelFileError(path, "safetensors header is not a JSON object");
    return header;
}

// "__metadata__": a map of strings (null is an absent map to serde, as to the Python loader).
void read_metadata(const std::string& path, const json& value, std::map<std::string, std::string>& metadata) {
    if (value.is_null()) return;
    if (!value.is_object()) throw ModelFileError(path, "__metadata__ is not an object");
    for (auto m = value.begin(); m != value.end(); ++m) {
        if (!m->is_string())
            throw ModelFileError(path, "not a valid safetensors file (__metadata__ entry '" + m.key() + "' is " +
                                           (m->is_number_integer() ? std::string("an integer")
                                            : m->is_number()       ? std::string("a number")
                                            : m->is_boolean()      ? std::string("a boolean")
                                            : m->is_null()         ? std::string("null")
                                            : m->is_array()        ? std::string("an array")
                                                                   : std::string("an object")) +
                                           ", not a string)");
        metadata[m.key()] = m->get<std::string>();
    }
}

// A JSON array of unsigned integers, as serde reads a `usize` list: 6.0, 6.9, -0 and true are
// not integers there (nlohmann-json would convert them). False when any element is not one.
bool read_usize_array(const json& v, std::vector<std::uint64_t>& out) {
    if (!v.is_array()) return false;
    for (const auto& d : v) {
        if (!d.is_number_unsigned()) return false;
        out.push_back(d.get<std::uint64_t>());
    }
    return true;
}

// One tensor's entry: F32, an integer shape, two offsets whose range holds exactly the shape's
// elements inside the data section of `data_len` bytes.
Entry read_tensor_entry(const std::string& path, const std::string& name, const json& info, std::uint64_t data_len) {
    Entry e{name, {}, 0, 0};
    std::vector<std::uint64_t> dims, offsets;
    try {
        if (info.at("dtype").get<std::string>() != "F32")
            throw ModelFileError(path, "tensor '" + name + "': dtype " + info.at("dtype").get<std::string>() +
                                           ", expected F32");
        if (!read_usize_array(info.at("shape"), dims))
            throw ModelFileError(path, "not a valid safetensors file (tensor '" + name +
                                           "': shape is not a list of non-negative integers)");
        if (!read_usize_array(info.at("data_offsets"), offsets) || offsets.size() != 2)
            throw ModelFileError(path, "not a valid safetensors file (tensor '" + name +
                                           "': data_offsets is not a list of two non-negative integers)");
    } catch (const json::exception&) {
        throw ModelFileError(path, "tensor '" + name + "': malformed entry in the header");
    }
    e.start = offsets[0];
    e.end = offsets[1];
    std::uint64_t count = 1;
    for (auto d : dims) {
        // Element counts past the data section cannot fit it; stopping here also keeps the
        // product from wrapping around 2^64 and passing the range check below.
        if (d != 0 && count > data_len / 4 / d) {
            count = std::numeric_limits<std::uint64_t>::max() / 8;
            break;
        }
        count *= d;
    }
    for (auto d : dims) e.shape.push_back(static_cast<std::int64_t>(std::min<std::uint64_t>(d, INT64_MAX)));
    if (!(e.start <= e.end && e.end <= data_len) || e.end - e.start != 4 * count)
        throw ModelFileError(path, "tensor '" + name + "': data range [" + std::to_string(e.start) + ", " +
                                       std::to_string(e.end) + ") does not fit shape " + shape_str(e.shape) +
                                       " in " + std::to_string(data_len) + " data bytes (truncated?)");
    return e;
}

// The safetensors format indexes its data section exactly: no overlap, no hole, nothing after
// the last tensor (bytes nothing reads are damage, or something hidden in the file). Checked
// against the file's real size before a byte of tensor data is read or allocated. Sorts `entries`.
void check_layout(const std::string& path, std::vector<Entry>& entries, std::uint64_t data_len) {
    std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
        return std::tie(a.start, a.end) < std::tie(b.start, b.end);
    });
    std::uint64_t covered = 0;
    for (const auto& e : entries) {
        if (e.start != covered)
            throw ModelFileError(path, "safetensors data section is not laid out tensor after tensor (bytes " +
                                           std::to_string(std::min(e.start, covered)) + " on)");
        covered = e.end;
    }
    if (covered != data_len)
        throw ModelFileError(path, "safetensors data section has " + std::to_string(data_len - covered) +
                                       " bytes after the last tensor");
}

// Only now the data: tensor by tensor, in file order, exactly the bytes declared. A failed
// allocation is the file's size speaking, reported as such rather than as std::bad_alloc.
void read_tensor_data(const std::string& path, std::ifstream& in, std::uint64_t data_start,
                      std::vector<Entry>& entries, std::uint64_t data_len, std::map<std::string, Tensor>& tensors) {
    try {
        for (auto& e : entries) {
            Tensor t;
            t.shape = std::move(e.shape);
            t.data.resize(static_cast<std::size_t>((e.end - e.start) / 4));
            in.seekg(static_cast<std::streamoff>(data_start + e.start));
            if (e.end > e.start &&  // little-endian hosts only
                !in.read(reinterpret_cast<char*>(t.data.data()), static_cast<std::streamsize>(e.end - e.start)))
                throw ModelFileError(path, "cannot read tensor '" + e.name + "' (the file changed while reading?)");
            tensors[e.name] = std::move(t);
        }
    } catch (const std::bad_alloc&) {
        throw ModelFileError(path, "needs " + std::to_string(data_len) +
                                       " bytes of tensor data, more than this process could allocate");
    }
}

}  // namespace

std::string shape_str(const std::vector<std::int64_t>& s) {
    std::ostringstream o;
    o << "(";
    for (std::size_t i = 0; i < s.size(); ++i) o << (i ? ", " : "") << s[i];
    o << (s.size() == 1 ? ",)" : ")");
    return o.str();
}

Container read_safetensors(const std::string& path) {
    check_file_kind(path);
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw ModelFileError(path, "no such file or not readable");
    const std::uint64_t size = file_size(path, in);
    const std::string text = read_header_text(path, in, size);
    const json header = parse_header(path, text);
    const std::uint64_t data_len = size - 8 - text.size();
    Container file;
    std::vector<Entry> entries;
    for (auto it = header.begin(); it != header.end(); ++it) {  // in key order, as the checks were written
        if (it.key() == "__metadata__")
            read_metadata(path, *it, file.metadata);
        else
            entries.push_back(read_tensor_entry(path, it.key(), *it, data_len));
    }
    check_layout(path, entries, data_len);
    read_tensor_data(path, in, 8 + text.size(), entries, data_len, file.tensors);
    return file;
}

}  // namespace hbrdf::model_file
