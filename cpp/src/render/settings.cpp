// hybridbrdf renderer — reading and checking the settings of settings.hpp.
#include "hybridbrdf/render/settings.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hbrdf::render {

namespace {

// Type names for "expected X, got Y" messages.
const char* kind_of(const SettingValue& v) {
    switch (v.index()) {
        case 0: return "a boolean";
        case 1:
        case 2: return "an integer";
        case 3: return "a number";
        case 4: return "a string";
        default: return std::get<OtherValue>(v).type_name.c_str();
    }
}

std::string format(double x) {
    std::ostringstream o;
    o.precision(9);
    o << x;
    return o.str();
}

std::string expected(const char* what, const SettingValue& v) {
    std::string got = kind_of(v);
    if (v.index() == 3) got += " (" + format(std::get<double>(v)) + ")";
    return std::string("expected ") + what + ", got " + got;
}

// An integer setting of member type T: bounds checked on the value as given
// (int64 or uint64), before it is converted to T.
template <typename T> std::string set_integer(T& out, const SettingInfo& info, const SettingValue& v) {
    // In double, exactly: the bounds are small integers or the type's limits,
    // and rounding a large value cannot move it across them.
    const double lo = std::max(info.min, double(std::numeric_limits<T>::min()));
    const double hi = std::min(info.max, double(std::numeric_limits<T>::max()));
    double x;
    std::string text;
    if (const auto* i = std::get_if<std::int64_t>(&v)) {
        x = double(*i);
        text = std::to_string(*i);
    } else if (const auto* u = std::get_if<std::uint64_t>(&v)) {
        x = double(*u);
        text = std::to_string(*u);
    } else {
        return expected("an integer", v);
    }
    if (x < lo) return "must be >= " + std::to_string(std::int64_t(lo)) + ", got " + text;
    if (x > hi) return "must be <= " + std::to_string(std::uint64_t(hi)) + ", got " + text;
    out = std::holds_alternative<std::int64_t>(v) ? T(std::get<std::int64_t>(v)) : T(std::get<std::uint64_t>(v));
    return "";
}

std::string set_float(float& out, const SettingInfo& info, const SettingValue& v) {
    double x;
    if (const auto* d = std::get_if<double>(&v)) x = *d;
    else if (const auto* i = std::get_if<std::int64_t>(&v)) x = double(*i);
    else if (const auto* u = std::get_if<std::uint64_t>(&v)) x = double(*u);
    else return expected("a number", v);
    if (!std::isfinite(x)) return "expected a finite number, got " + format(x);
    const double lo = std::max(info.min, -double(FLT_MAX)), hi = std::min(info.max, double(FLT_MAX));
    if (x < lo) return "must be >= " + format(lo) + ", got " + format(x);
    if (x > hi) return "must be <= " + format(hi) + ", got " + format(x);
    out = float(x);
    return "";
}

}  // namespace

const SettingInfo* find_setting(std::string_view name) {
    for (const SettingInfo& info : kRenderSettings)
        if (name == info.name) return &info;
    return nullptr;
}

const char* setting_type(const SettingInfo& info) {
    switch (info.field.index()) {
        case 0:
        case 1: return "int";
        case 2: return "float";
        case 3: return "bool";
        default: return "str";
    }
}

SettingValue get_setting(const RenderSettings& s, const SettingInfo& info) {
    switch (info.field.index()) {
        case 0: return std::int64_t(s.*std::get<0>(info.field));
        case 1: return s.*std::get<1>(info.field);
        case 2: return double(s.*std::get<2>(info.field));
        case 3: return s.*std::get<3>(info.field);
        default: return std::string(sampler_name(s.*std::get<4>(info.field)));
    }
}

std::string set_setting(RenderSettings& s, const SettingInfo& info, const SettingValue& v) {
    switch (info.field.index()) {
        case 0: return set_integer(s.*std::get<0>(info.field), info, v);
        case 1: return set_integer(s.*std::get<1>(info.field), info, v);
        case 2: return set_float(s.*std::get<2>(info.field), info, v);
        case 3:
            if (!std::holds_alternative<bool>(v)) return expected("true or false", v);
            s.*std::get<3>(info.field) = std::get<bool>(v);
            return "";
        default:
            if (!std::holds_alternative<std::string>(v)) return expected("a string", v);
            try {
                s.*std::get<4>(info.field) = parse_sampler(std::get<std::string>(v));
            } catch (const std::invalid_argument& e) {
                return e.what();
            }
            return "";
    }
}

void check_settings(const RenderSettings& s) {
    for (const SettingInfo& info : kRenderSettings) {
        RenderSettings scratch = s;  // set_setting on a copy: the same checks as for a scene file
        const std::string problem = set_setting(scratch, info, get_setting(s, info));
        if (!problem.empty()) throw std::invalid_argument(std::string(info.name) + ": " + problem);
    }
}

}  // namespace hbrdf::render
