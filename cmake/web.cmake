# The web build (docs/web.md), included by the top-level CMakeLists.txt under emscripten
# (`emcmake cmake -S . -B build-web`, which .ci/web runs). It builds the core, PNG output, the
# viewer and the command line for WebAssembly, and the page (src/web) from them.
#
# Dependencies, none downloaded at build time: emscripten's prebuilt sysroot (libc, libc++, GLFW 3,
# WebGL2); Debian's header-only nlohmann-json and CLI11; Dear ImGui's headers and backends from
# libimgui-dev, and its four core sources from Debian's source package of the same version
# (FLATLAND_IMGUI_SOURCES; libimgui-dev ships them compiled for the host only, and .ci/web fetches
# the source package with apt-get source).
set(FLATLAND_IMGUI_SOURCES "" CACHE PATH
    "Dear ImGui's core sources (imgui.cpp, imgui_draw.cpp, imgui_tables.cpp, imgui_widgets.cpp) of the version libimgui-dev has")
foreach(source imgui.cpp imgui_draw.cpp imgui_tables.cpp imgui_widgets.cpp)
  if(NOT EXISTS "${FLATLAND_IMGUI_SOURCES}/${source}")
    message(FATAL_ERROR "FLATLAND_IMGUI_SOURCES='${FLATLAND_IMGUI_SOURCES}' has no ${source}: run .ci/web, "
                        "which fetches Debian's imgui source package, or point it at Dear ImGui's sources")
  endif()
endforeach()

# The host's /usr/include cannot be on the include path (it holds glibc's headers): a folder of
# links to the libraries' own folders brings in just those.
set(FLATLAND_HOST_INCLUDE ${PROJECT_BINARY_DIR}/host-include)
file(MAKE_DIRECTORY ${FLATLAND_HOST_INCLUDE})
foreach(folder nlohmann CLI imgui)
  if(NOT EXISTS /usr/include/${folder})
    message(FATAL_ERROR "/usr/include/${folder} is missing: install nlohmann-json3-dev, libcli11-dev and "
                        "libimgui-dev (.ci/setup does)")
  endif()
  file(CREATE_LINK /usr/include/${folder} ${FLATLAND_HOST_INCLUDE}/${folder} SYMBOLIC)
endforeach()
foreach(library nlohmann_json::nlohmann_json CLI11::CLI11)
  add_library(${library} INTERFACE IMPORTED)
  set_target_properties(${library} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES ${FLATLAND_HOST_INCLUDE}
                                              INTERFACE_SYSTEM_INCLUDE_DIRECTORIES ${FLATLAND_HOST_INCLUDE})
endforeach()
# One thread: no -pthread (which would need a cross-origin isolated page).
add_library(Threads::Threads INTERFACE IMPORTED)

# Exceptions are caught, as on the desktop: CLI11 reports parse errors with them, and the commands
# turn an allocation failure into a one-line error.
target_compile_options(flatland_options INTERFACE -fexceptions)
target_link_options(flatland_options INTERFACE -fexceptions)

add_subdirectory(src/flatland)
add_subdirectory(src/png)
add_subdirectory(src/viewer)
add_subdirectory(src/app)
add_subdirectory(src/web)
