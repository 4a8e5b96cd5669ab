# `cmake --install build --prefix P`: the programs in P/bin, and the C++ client library as a
# package another project finds with find_package(skinserve CONFIG) (target
# skinserve::client) or pkg-config (skinserve-client): its headers, the headers they include
# (the wire codec, the data model, the encodings, the animation runtime's types, the
# generated protobuf/gRPC code) and the static libraries it links (docs/client-library.md).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(TARGETS skinserve skinserve-cli skinserve-load RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# The client and the libraries of ours it links, exported as skinserve::<name>.
set(SKINSERVE_CLIENT_LIBRARIES skinserve_client skinserve_wire skinserve_proto
                               skinserve_encoding skinserve_animation skinserve_model)
foreach(library IN LISTS SKINSERVE_CLIENT_LIBRARIES)
  string(REPLACE "skinserve_" "" export_name ${library})
  set_target_properties(${library} PROPERTIES EXPORT_NAME ${export_name})
endforeach()
install(TARGETS ${SKINSERVE_CLIENT_LIBRARIES} EXPORT skinserveTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
foreach(headers client/include proto/wire/include core/model/include core/encoding/include
                core/animation/include)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${headers}/skinserve
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
endforeach()
# The generated messages and stubs (proto/CMakeLists.txt writes them there): skin_client.h
# exposes them (v1::ServerStats, ...).
install(DIRECTORY ${PROJECT_BINARY_DIR}/proto/generated/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.pb.h")

set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/skinserve)
install(EXPORT skinserveTargets NAMESPACE skinserve:: DESTINATION ${config_dir})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/skinserveConfig.cmake.in
                              ${CMAKE_CURRENT_BINARY_DIR}/skinserveConfig.cmake
                              INSTALL_DESTINATION ${config_dir})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/skinserveConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/skinserveConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/skinserveConfigVersion.cmake
        DESTINATION ${config_dir})

# pkg-config: the prefix relative to the .pc file, so that `--prefix` at install time holds.
file(RELATIVE_PATH SKINSERVE_PC_TO_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
string(REGEX REPLACE "/$" "" SKINSERVE_PC_TO_PREFIX ${SKINSERVE_PC_TO_PREFIX})
configure_file(${CMAKE_CURRENT_LIST_DIR}/skinserve-client.pc.in
               ${CMAKE_CURRENT_BINARY_DIR}/skinserve-client.pc @ONLY)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/skinserve-client.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
