# One place for compiler warnings and sanitizer flags (STYLE.md 12).

# ASan and TSan bring their own malloc: a binary that replaces the allocator (the
# no-allocation tests' counting_allocator.h) cannot run beside them (it dies at
# once), so those binaries are left out of such builds, like rack::rt_hooks.
if(RACK_SANITIZER MATCHES "address|thread")
  set(RACK_SANITIZER_OWNS_MALLOC ON)
else()
  set(RACK_SANITIZER_OWNS_MALLOC OFF)
endif()
function(rack_set_warnings target)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wshadow -Wconversion -Wsign-conversion -Wold-style-cast
    -Wnon-virtual-dtor -Woverloaded-virtual -Wnull-dereference -Wformat=2)
  if(RACK_WERROR)  # CMakeLists.txt: CI builds with it
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(RACK_SANITIZER)
    target_compile_options(${target} PRIVATE -fsanitize=${RACK_SANITIZER} -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=${RACK_SANITIZER})
  endif()
endfunction()
