# rack_add_opencv_class(): a class that links OpenCV (Camera, ObjRecogCamera), one
# plug-in each; OpenCV stays out of rackd and rack_components.
#
#   rack_add_opencv_class(LIBRARY rack_camera           # a static library of the sources
#     SOURCES camera.cpp                                # (relative to the folder)
#     OPENCV core imgproc imgcodecs videoio             # the OpenCV modules it needs
#     PACKAGE libopencv-dev                             # the Debian package that has them
#     NAME Camera ID 0x12 ... PLUGIN camera)            # the rest: rack_add_class's
#
# The sources become the static library LIBRARY (tests link it): OpenCV PRIVATE, its
# headers SYSTEM (they trip our warning set), components/ on the public include path;
# the class is declared with rack_add_class(... LIBS LIBRARY). Without those OpenCV
# modules the class is declared UNAVAILABLE: a warning that names the package, no
# library, and its id still in rack/components/class_ids.h.
include_guard(GLOBAL)

function(rack_add_opencv_class)
  cmake_parse_arguments(PARSE_ARGV 0 O "" "LIBRARY;PACKAGE" "OPENCV;SOURCES")
  foreach(required LIBRARY PACKAGE OPENCV SOURCES)
    if(NOT O_${required})
      message(FATAL_ERROR "rack_add_opencv_class: ${required} missing (${CMAKE_CURRENT_LIST_FILE})")
    endif()
  endforeach()
  find_package(OpenCV QUIET COMPONENTS ${O_OPENCV})
  if(NOT OpenCV_FOUND)
    list(JOIN O_OPENCV " " modules)
    rack_add_class(${O_UNPARSED_ARGUMENTS}
                   UNAVAILABLE "OpenCV (${modules}) not found (apt-get install ${O_PACKAGE})")
    return()
  endif()
  add_library(${O_LIBRARY} STATIC ${O_SOURCES})
  target_include_directories(${O_LIBRARY} PUBLIC ${PROJECT_SOURCE_DIR}/components)
  target_include_directories(${O_LIBRARY} SYSTEM PRIVATE ${OpenCV_INCLUDE_DIRS})
  target_link_libraries(${O_LIBRARY} PUBLIC rack::core rack::interfaces PRIVATE ${OpenCV_LIBS})
  rack_set_warnings(${O_LIBRARY})
  rack_add_class(${O_UNPARSED_ARGUMENTS} LIBS ${O_LIBRARY})
endfunction()
