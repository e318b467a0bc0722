# Writes nirslam.1.gz from the built program's own help, so the man page cannot drift from the CLI.
# Run by the nirslam_manpage target (packaging/CMakeLists.txt) after every link of the binary:
#   cmake -DNIRSLAM=<binary> -DHELP2MAN=<help2man> -DGZIP=<gzip> -DVERSION=<x.y.z>
#         -DSECTIONS=<packaging/manpage-sections.roff> -DWORK_DIR=<scratch folder> -DOUTPUT=<.../nirslam.1.gz>
#         -P manpage.cmake
# help2man turns `nirslam --help` into the page (synopsis, options, the subcommand list, the examples);
# every subcommand's own --help becomes a subsection of SUBCOMMANDS, converted here because help2man
# reads one help text only. FILES, ENVIRONMENT, SEE ALSO come from manpage-sections.roff.

cmake_policy(VERSION 3.25)

foreach(var NIRSLAM HELP2MAN GZIP VERSION SECTIONS WORK_DIR OUTPUT)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "manpage.cmake: -D${var}=... is required")
  endif()
endforeach()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}/bin")
# CLI11 prints argv[0] in its usage lines: run the program as plain `nirslam` from PATH, not by its
# build-tree path.
file(CREATE_LINK "${NIRSLAM}" "${WORK_DIR}/bin/nirslam" SYMBOLIC)
set(program "${WORK_DIR}/bin/nirslam")

# `nirslam [SUBCOMMAND] --help`, split into lines. Semicolons are CMake's list separator: they travel
# as a placeholder and come back in roff_escape.
function(help_lines out_var)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env "PATH=${WORK_DIR}/bin:$ENV{PATH}" nirslam ${ARGN} --help
                  OUTPUT_VARIABLE help RESULT_VARIABLE result ERROR_VARIABLE errors)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "nirslam ${ARGN} --help failed (${result}): ${errors}")
  endif()
  string(REPLACE ";" "@SEMICOLON@" help "${help}")
  string(REPLACE "\n" ";" lines "${help}")
  set(${out_var} "${lines}" PARENT_SCOPE)
endfunction()

# Plain text as roff: backslashes, hyphens (as \- so they stay ASCII hyphens for copy and search),
# and a leading dot or quote (which would start a request).
function(roff_escape text out_var)
  string(REPLACE "\\" "\\e" text "${text}")
  string(REPLACE "-" "\\-" text "${text}")
  string(REPLACE "@SEMICOLON@" ";" text "${text}")
  if(text MATCHES "^[.']")
    set(text "\\&${text}")
  endif()
  set(${out_var} "${text}" PARENT_SCOPE)
endfunction()

# One CLI11 entry: two spaces, names (comma-separated), an optional TYPE in capitals (TEXT:FILE,
# INT=3, INT:INT in [1 - 9]=3, TEXT ... REQUIRED), then its description after blanks (or on the
# following, deeper lines).
set(entry_regex "^  ([^ ]+)( ([A-Z][A-Z0-9_]*([:=][^ ]*)?( in \\[[^]]*\\][^ ]*)?( \\.\\.\\.)?( REQUIRED)?))?( +(.*))?$")

help_lines(main_lines)
set(subcommands "")
set(in_subcommands FALSE)
foreach(line IN LISTS main_lines)
  if(line MATCHES "^[A-Za-z].*:$")
    set(in_subcommands FALSE)
    if(line STREQUAL "Subcommands:" OR line STREQUAL "SUBCOMMANDS:")
      set(in_subcommands TRUE)
    endif()
  elseif(in_subcommands AND line MATCHES "^  ([a-z][a-z0-9-]*) ")
    list(APPEND subcommands "${CMAKE_MATCH_1}")
  endif()
endforeach()
if(NOT subcommands)
  message(FATAL_ERROR "no subcommands found in `nirslam --help`")
endif()

set(roff "[SUBCOMMANDS]\n")
foreach(subcommand IN LISTS subcommands)
  help_lines(lines ${subcommand})
  string(APPEND roff ".SS \"nirslam ${subcommand}\"\n")
  set(section "description")
  foreach(line IN LISTS lines)
    if(line STREQUAL "")
      continue()
    elseif(line MATCHES "^Usage: [^ ]*nirslam (.*)$")
      roff_escape("${CMAKE_MATCH_1}" usage)
      string(APPEND roff ".PP\n\\fBnirslam\\fR ${usage}\n")
    elseif(line MATCHES "^(Positionals|POSITIONALS):$")
      set(section "positionals")
      string(APPEND roff ".PP\n\\fIArguments:\\fR\n")
    elseif(line MATCHES "^(Options|OPTIONS):$")
      set(section "options")
      string(APPEND roff ".PP\n\\fIOptions:\\fR\n")
    elseif(section STREQUAL "description")
      roff_escape("${line}" text)
      string(APPEND roff "${text}\n")
    elseif(line MATCHES "^   +(.*)$")  # a description continued below its entry
      roff_escape("${CMAKE_MATCH_1}" text)
      string(APPEND roff "${text}\n")
    elseif(line MATCHES "${entry_regex}")
      set(names "${CMAKE_MATCH_1}")
      set(type "${CMAKE_MATCH_3}")
      set(description "${CMAKE_MATCH_9}")
      if(names STREQUAL "-h,--help")
        continue()  # every subcommand has it; the page says so once, under OPTIONS
      endif()
      string(REPLACE "," ";" name_list "${names}")
      set(bold_names "")
      foreach(name IN LISTS name_list)
        roff_escape("${name}" name)
        list(APPEND bold_names "\\fB${name}\\fR")
      endforeach()
      list(JOIN bold_names ", " bold_names)
      roff_escape("${type}" type)
      roff_escape("${description}" description)
      string(APPEND roff ".TP\n${bold_names} \\fI${type}\\fR\n")
      if(NOT description STREQUAL "")  # else it follows on the next, deeper lines
        string(APPEND roff "${description}\n")
      endif()
    else()
      roff_escape("${line}" text)
      string(APPEND roff ".PP\n${text}\n")
    endif()
  endforeach()
endforeach()

file(READ "${SECTIONS}" extra_sections)
file(WRITE "${WORK_DIR}/nirslam.h2m" "${roff}\n${extra_sections}")

execute_process(
  COMMAND ${CMAKE_COMMAND} -E env "PATH=${WORK_DIR}/bin:$ENV{PATH}"
          ${HELP2MAN} --no-info --section=1 --version-string=${VERSION}
          "--name=near-infrared visual SLAM and illuminator advice for field camera rigs"
          --include=${WORK_DIR}/nirslam.h2m --output=${WORK_DIR}/nirslam.1 nirslam
  RESULT_VARIABLE result ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "help2man failed (${result}): ${errors}")
endif()
# -n: no name or time stamp in the archive, so the same page gives the same bytes.
execute_process(COMMAND ${GZIP} -9 -n -f "${WORK_DIR}/nirslam.1" RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "gzip failed (${result})")
endif()
file(COPY_FILE "${WORK_DIR}/nirslam.1.gz" "${OUTPUT}")
