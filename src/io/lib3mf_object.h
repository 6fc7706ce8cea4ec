// Lib3mfObject: owns one reference-counted object of lib3mf 1.8's C interface and releases it,
// for the 3MF writer and the tests' reader alike.
#pragma once

#include <Model/COM/NMR_DLLInterfaces.h>

namespace typemerge::io {

class Lib3mfObject {
 public:
  Lib3mfObject() = default;
  Lib3mfObject(const Lib3mfObject&) = delete;
  Lib3mfObject& operator=(const Lib3mfObject&) = delete;
  ~Lib3mfObject() {
    if (object_ != nullptr) NMR::lib3mf_release(object_);
  }
  // Where a lib3mf call writes the object it hands out.
  template <typename T>
  T** out() {
    return reinterpret_cast<T**>(&object_);
  }
  template <typename T>
  T* get() const {
    return static_cast<T*>(object_);
  }

 private:
  NMR::PLib3MFBase* object_ = nullptr;
};

}  // namespace typemerge::io
