# Man pages of the installed programs, generated at build time from their own --help and
# --version by help2man (Debian's help2man; scripts/install-deps.sh), into <build>/man and
# installed into share/man/man1. Without help2man the build goes on without them.
find_program(SKINSERVE_HELP2MAN help2man)
if(NOT SKINSERVE_HELP2MAN)
  message(STATUS "help2man not found: no man pages (apt-get install help2man)")
  return()
endif()
set(man_pages "")
set(skinserve_what "the gRPC skinning server (remote linear blend skinning)")
set(skinserve-cli_what "upload meshes, skin frames and check a skinserve server")
set(skinserve-load_what "load client of skinserve: throughput, latency and capacity")
foreach(program skinserve skinserve-cli skinserve-load)
  set(page ${PROJECT_BINARY_DIR}/man/${program}.1)
  add_custom_command(
    OUTPUT ${page}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${PROJECT_BINARY_DIR}/man
    COMMAND ${SKINSERVE_HELP2MAN} --no-info --no-discard-stderr --section=1
            --source=skinserve "--name=${${program}_what}" --output=${page}
            $<TARGET_FILE:${program}>
    DEPENDS ${program}
    COMMENT "Generating the man page of ${program} (help2man)"
    VERBATIM)
  list(APPEND man_pages ${page})
endforeach()
add_custom_target(skinserve_man_pages ALL DEPENDS ${man_pages})
install(FILES ${man_pages} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
