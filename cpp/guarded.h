// What both C++ bridges do with exceptions: turn each into a std::runtime_error whose
// message is capped, which cxx hands to Rust as an Err. Library exception texts can
// embed file contents (a corrupt VDB once produced a 1.5 GB message).
#pragma once

#include <exception>
#include <stdexcept>
#include <string>

namespace nimbus_cpp {

constexpr size_t kMaxMessage = 512;

inline std::string capped(const char* what) {
    std::string s = what ? what : "unknown error";
    if (s.size() > kMaxMessage) {
        s.resize(kMaxMessage);
        s += "... (truncated)";
    }
    return s;
}

// Runs `body`; any exception leaves as a std::runtime_error with a capped message
// (`library` names the library in the message of a non-std exception).
template <typename F>
auto guarded(const char* library, F&& body) -> decltype(body()) {
    try {
        return body();
    } catch (const std::exception& e) {
        throw std::runtime_error(capped(e.what()));
    } catch (...) {
        throw std::runtime_error(std::string("unknown C++ exception in ") + library);
    }
}

}  // namespace nimbus_cpp
