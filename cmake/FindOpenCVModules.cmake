# Finds the few OpenCV modules the project uses from Debian's split packages
# (libopencv-core-dev, -imgproc-dev, -photo-dev). Debian ships OpenCV's CMake
# config only in the libopencv-dev meta package, which drags in some 140 unrelated packages.
# Defines OpenCV::core, OpenCV::imgproc, OpenCV::photo.
find_path(OpenCVModules_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
set(_found TRUE)
foreach(_module core imgproc photo)
  find_library(OpenCVModules_${_module}_LIBRARY opencv_${_module})
  if(NOT OpenCVModules_${_module}_LIBRARY)
    set(_found FALSE)
  elseif(NOT TARGET OpenCV::${_module})
    add_library(OpenCV::${_module} SHARED IMPORTED)
    set_target_properties(OpenCV::${_module} PROPERTIES
      IMPORTED_LOCATION "${OpenCVModules_${_module}_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${OpenCVModules_INCLUDE_DIR}")
  endif()
endforeach()
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCVModules REQUIRED_VARS OpenCVModules_INCLUDE_DIR _found)
