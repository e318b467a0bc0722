# bash completion for nirslam                                      -*- shell-script -*-
#
# Installed as /usr/share/bash-completion/completions/nirslam (loaded on first use by bash-completion);
# without bash-completion, `source` this file from ~/.bashrc.
#
# Subcommands, options, which options take a value, their choices ({a,b,c}), file or folder
# arguments and positionals are read from the program's own --help (CLI11's layout) the first time
# they are needed in a shell, then cached. So the completion cannot go stale when a subcommand or an
# option is added, and it completes whatever binary is typed: nirslam, ./build/nirslam, ...
# Only the values that --help describes in prose (scene names, motions, ...) are listed here.
# tests/app/test_completion.cpp checks every subcommand and option of --help is offered.

declare -gA _nirslam_options _nirslam_valued _nirslam_kinds _nirslam_subcommands _nirslam_positionals _nirslam_sources

# Reads `PROGRAM [SUBCOMMAND] --help` once per shell. Keys are "PROGRAM|SUBCOMMAND".
_nirslam_read_help() {
  local program=$1 subcommand=$2 key="$1|$2"
  [[ -n ${_nirslam_options[$key]+set} ]] && return 0
  local help line section="" names type name options="" valued="" subcommands="" positionals=""
  help=$("$program" ${subcommand:+"$subcommand"} --help 2>/dev/null) || help=""
  # An entry starts two spaces in ("  -o,--out TEXT=x  Output folder"); deeper lines continue a description.
  local entry='^  ([^ ]+)( ([A-Z][A-Z0-9_]*([:=][^ ]*)?( \.\.\.)?)( |$))?'
  while IFS= read -r line; do
    case $line in
      Options:|OPTIONS:) section=options; continue ;;
      Subcommands:|SUBCOMMANDS:) section=subcommands; continue ;;
      Positionals:|POSITIONALS:) section=positionals; continue ;;
      [^\ ]*:) section=""; continue ;;  # any other heading (Examples:) ends the section
    esac
    [[ $line =~ $entry ]] || continue
    names=${BASH_REMATCH[1]} type=${BASH_REMATCH[3]}
    case $section in
      options)
        for name in ${names//,/ }; do
          options+=" $name"
          if [[ -n $type ]]; then
            valued+=" $name"
            _nirslam_kinds["$key|$name"]=$(_nirslam_kind_of "$type")
          fi
        done
        ;;
      subcommands) subcommands+=" $names" ;;
      positionals) positionals+=" $(_nirslam_kind_of "$type")" ;;
    esac
  done <<< "$help"
  _nirslam_options[$key]=$options
  _nirslam_valued[$key]="$valued "
  _nirslam_subcommands[$key]=$subcommands
  _nirslam_positionals[$key]=$positionals
  # Sources a positional "source"/"sequence" accepts besides folders: 'sim:tunnel', ..., 'demo'.
  local sources="" rest=$help found
  while [[ $rest =~ sim:[a-z]+|\'demo\' ]]; do
    found=${BASH_REMATCH[0]//\'/}
    [[ " $sources " == *" $found "* ]] || sources+=" $found"
    rest=${rest#*"${BASH_REMATCH[0]}"}
  done
  _nirslam_sources[$key]=$sources
}

# What a value of this CLI11 type completes to: "{a b c}" choices, "file", "dir", "number" or "text".
_nirslam_kind_of() {
  local type=$1
  if [[ $type =~ \{([^}]*)\} ]]; then
    local choices=${BASH_REMATCH[1]}
    echo "{${choices//,/ }}"
  elif [[ $type == *:FILE* ]]; then echo file
  elif [[ $type == *:DIR* ]]; then echo dir
  elif [[ $type == INT* || $type == UINT* || $type == FLOAT* || $type == NUMBER* ]]; then echo number
  else echo text
  fi
}

# Values that --help only names in prose.
_nirslam_prose_values() {
  case $1 in
    --scene | --scenes) echo "room outdoor parking tunnel" ;;
    --motion) echo "handheld vehicle robot tripod" ;;
    --camera) echo "pinhole fov" ;;
    --response) echo "linear gamma log filmic" ;;
    --exposure) echo "auto" ;;
    --modes) echo "quality odometry calibrated" ;;
    --bits) echo "8 16" ;;
  esac
}

_nirslam_complete_files() {  # dir | file, for the word $1
  compopt -o filenames 2>/dev/null
  if [[ $2 == dir ]]; then
    mapfile -t COMPREPLY < <(compgen -d -- "$1")
  else
    mapfile -t COMPREPLY < <(compgen -f -- "$1")
  fi
}

# Completes the value of option $2 of subcommand key $1, for the word $3.
_nirslam_complete_value() {
  local key=$1 option=$2 cur=$3 kind prose
  kind=${_nirslam_kinds["$key|$option"]}
  prose=$(_nirslam_prose_values "$option")
  if [[ $kind == \{*\} ]]; then
    kind=${kind#\{} && kind=${kind%\}}
    mapfile -t COMPREPLY < <(compgen -W "$kind" -- "$cur")
  elif [[ -n $prose ]]; then
    # Comma-separated lists (--scenes room,tunnel): complete the item after the last comma.
    local done_items="" item=$cur
    if [[ $cur == *,* ]]; then done_items=${cur%,*}, item=${cur##*,}; fi
    mapfile -t COMPREPLY < <(compgen -P "$done_items" -W "$prose" -- "$item")
  elif [[ $kind == file || $kind == dir || $kind == text ]]; then
    _nirslam_complete_files "$cur" "$kind"
  fi
}

_nirslam() {
  COMPREPLY=()
  # Words as typed, split on blanks only: bash's own COMP_WORDS also splits at ':' and '=' (sim:tunnel,
  # --out=DIR).
  local line=${COMP_LINE:0:COMP_POINT}
  local -a words
  read -ra words <<< "$line"
  if [[ ${#words[@]} -eq 0 || $line =~ [[:space:]]$ ]]; then words+=(""); fi
  local cur=${words[-1]} program=${words[0]}
  [[ $program == "~"* ]] && program=$HOME${program:1}
  command -v "$program" > /dev/null 2>&1 || return 0

  _nirslam_read_help "$program" ""
  local key="$program|" subcommand="" i word
  local -a positionals_given=()
  # Walk the words before the current one: the subcommand, skipping the values of valued options.
  for ((i = 1; i < ${#words[@]} - 1; i++)); do
    word=${words[i]}
    if [[ $word == -* ]]; then
      [[ $word != *=* && ${_nirslam_valued[$key]} == *" $word "* ]] && ((i++))
    elif [[ -z $subcommand && " ${_nirslam_subcommands["$program|"]} " == *" $word "* ]]; then
      subcommand=$word key="$program|$word"
      _nirslam_read_help "$program" "$subcommand"
    else
      positionals_given+=("$word")
    fi
  done

  local prev=""
  ((${#words[@]} > 1)) && prev=${words[-2]}
  if [[ $cur == --*=* ]]; then  # --out=DIR: bash completes the part after '=' only
    _nirslam_complete_value "$key" "${cur%%=*}" "${cur#*=}"
  elif [[ $prev == -* && $prev != *=* && ${_nirslam_valued[$key]} == *" $prev "* ]]; then
    _nirslam_complete_value "$key" "$prev" "$cur"
  elif [[ $cur == -* ]]; then
    mapfile -t COMPREPLY < <(compgen -W "${_nirslam_options[$key]}" -- "$cur")
  elif [[ -z $subcommand && ${#positionals_given[@]} -eq 0 ]]; then
    mapfile -t COMPREPLY < <(compgen -W "${_nirslam_subcommands[$key]}" -- "$cur")
  else
    # The next positional; the last one takes every further word (image lists, dataset folders).
    local -a kinds
    read -ra kinds <<< "${_nirslam_positionals[$key]}"
    ((${#kinds[@]} > 0)) || return 0
    local index=${#positionals_given[@]}
    ((index >= ${#kinds[@]})) && index=$((${#kinds[@]} - 1))
    local kind=${kinds[index]}
    if [[ -n ${_nirslam_sources[$key]} && $kind == text ]]; then  # a source: sim:SCENE, demo or a folder
      mapfile -t COMPREPLY < <(compgen -W "${_nirslam_sources[$key]}" -- "$cur")
      local -a folders
      mapfile -t folders < <(compgen -d -- "$cur")
      COMPREPLY+=("${folders[@]}")
      ((${#folders[@]} > 0)) && compopt -o filenames 2>/dev/null
    elif [[ $kind == \{*\} ]]; then
      kind=${kind#\{} && kind=${kind%\}}
      mapfile -t COMPREPLY < <(compgen -W "$kind" -- "$cur")
    elif [[ $kind != number ]]; then
      _nirslam_complete_files "$cur" "$kind"
    fi
  fi

  # bash replaces only the part of the word after its last ':' (COMP_WORDBREAKS): drop what comes before.
  if [[ $cur == *:* && $COMP_WORDBREAKS == *:* ]]; then
    local prefix=${cur%"${cur##*:}"}
    for i in "${!COMPREPLY[@]}"; do COMPREPLY[i]=${COMPREPLY[i]#"$prefix"}; done
  fi
  return 0
}

complete -F _nirslam nirslam
