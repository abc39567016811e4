# bash completion for RACK-RT's tools: rackd, rackctl, gdos, rack-gui, rack-backtrace,
# rack-devsim, rack-foxglove. Installed to share/bash-completion/completions (one link per tool, so
# bash-completion loads it on first use); by hand: source tools/completion/rack.bash
#
# rackctl completes its commands and options, and component names (NAME) from a quick
# discovery on the network (rackctl list --json, 300 ms); RACK_COMPLETE_NO_DISCOVERY=1
# turns that off. File options complete file names.

_rack_words() {  # _rack_words WORDS: the candidates for the current word
  local cur=${COMP_WORDS[COMP_CWORD]}
  COMPREPLY=($(compgen -W "$1" -- "$cur"))
}

_rack_files() {  # _rack_files [GLOB]: file names (and directories)
  local cur=${COMP_WORDS[COMP_CWORD]}
  if [[ -n $1 ]]; then
    COMPREPLY=($(compgen -f -X "!$1" -- "$cur") $(compgen -d -- "$cur"))
  else
    COMPREPLY=($(compgen -f -- "$cur"))
  fi
  compopt -o filenames 2>/dev/null
}

_rackd() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  case $prev in
    --crash-dir) COMPREPLY=($(compgen -d -- "$cur")); compopt -o filenames 2>/dev/null; return ;;
    --lcm|--duration|--status) return ;;
  esac
  if [[ $cur == -* ]]; then
    _rack_words "--check --list-classes --json --duration --status --lcm --crash-dir --help --version"
  else
    _rack_files '*.@(yaml|yml)'
  fi
}

_RACKCTL_COMMANDS="list hosts on off status latency params classes set-param get-data watch send hz bw doctor keygen threads trace graph alloc help"
_RACKCTL_OPTIONS="--lcm --timeout --retries --discover-ms --host-file --key-file --help --version"

# Command-specific options (as rackctl help COMMAND lists them).
_rackctl_command_options() {
  case $1 in
    list|hosts|status|latency|params|classes|doctor) echo "--json" ;;
    get-data) echo "--time" ;;
    watch) echo "--period --count" ;;
    send) echo "--i64" ;;
    hz|bw) echo "--window --period --count --json" ;;
    trace) echo "--duration --out --host" ;;
    graph) echo "--live --format --out --rackd" ;;
    alloc) echo "--live --json --rackd" ;;
  esac
}

# Component names that answer discovery (one per line), for NAME arguments; the
# network options given so far (--lcm, --host-file, --key-file) are passed on.
_rackctl_names() {
  [[ -n $RACK_COMPLETE_NO_DISCOVERY ]] && return
  local -a net=()
  local i
  for ((i = 1; i < ${#_rackctl_w[@]} - 1; i++)); do
    case ${_rackctl_w[i]} in
      --lcm|--host-file|--key-file) net+=("${_rackctl_w[i]}" "${_rackctl_w[i+1]}") ;;
      --lcm=*|--host-file=*|--key-file=*) net+=("${_rackctl_w[i]}") ;;
    esac
  done
  "${_rackctl_w[0]}" "${net[@]}" --discover-ms 300 --timeout 300 --retries 0 list --json 2>/dev/null |
    grep -o '"name":"[^"]*"' | cut -d'"' -f4
}

_rackctl() {
  # The words of the line up to the cursor, split at blanks only: bash's COMP_WORDS
  # also splits at ':' and '=', which would cut an LCM URL into pieces.
  local line=${COMP_LINE:0:COMP_POINT}
  _rackctl_w=()
  read -ra _rackctl_w <<< "$line"
  [[ -z $line || $line == *[[:blank:]] ]] && _rackctl_w+=("")
  local count=${#_rackctl_w[@]}
  local cur=${_rackctl_w[count-1]} prev=""
  ((count > 1)) && prev=${_rackctl_w[count-2]}
  case $prev in
    --host-file) _rack_files '*.@(yaml|yml)'; return ;;
    --key-file|--rackd) _rack_files; return ;;
    --out) _rack_files '*.json'; return ;;
    --format) _rack_words "dot svg json"; return ;;
    --lcm|--timeout|--retries|--discover-ms|--time|--period|--count|--window|--i64|--duration|--host) return ;;
  esac
  # The command and its position among the words that are not options.
  local cmd="" i n=0 w
  for ((i = 1; i < count - 1; i++)); do
    w=${_rackctl_w[i]}
    case $w in
      --lcm|--timeout|--retries|--discover-ms|--host-file|--key-file|--time|--period|--count|--window|--i64|--duration|--out|--host|--format|--rackd)
        ((i++)); continue ;;
      -*) continue ;;
    esac
    [[ -z $cmd ]] && cmd=$w || ((n++))
  done
  if [[ $cur == -* ]]; then
    COMPREPLY=($(compgen -W "$_RACKCTL_OPTIONS $(_rackctl_command_options "$cmd")" -- "$cur"))
    return
  fi
  if [[ -z $cmd ]]; then
    COMPREPLY=($(compgen -W "$_RACKCTL_COMMANDS" -- "$cur"))
    return
  fi
  case $cmd in
    help) ((n == 0)) && COMPREPLY=($(compgen -W "$_RACKCTL_COMMANDS" -- "$cur")) ;;
    keygen) ((n == 0)) && _rack_files ;;
    graph|alloc) _rack_files '*.@(yaml|yml)' ;;
    list|hosts|doctor|classes|threads) ;;
    trace)
      local IFS=$'\n'
      COMPREPLY=($(compgen -W "all"$'\n'"$(_rackctl_names)" -- "$cur"))
      ;;
    on|off|status|latency|params|get-data|watch|hz|bw|set-param|send)
      if ((n == 0)); then
        local IFS=$'\n'
        COMPREPLY=($(compgen -W "$(_rackctl_names)" -- "$cur"))
      elif [[ $cmd == send && n -eq 1 ]]; then
        # The command names rackctl knows (rackctl help send: "  CLASS: NAME number ...").
        COMPREPLY=($(compgen -W "$("${_rackctl_w[0]}" help send 2>/dev/null |
          sed -n 's/^  [A-Za-z0-9]*: \([A-Z_][A-Z0-9_]*\) .*/\1/p' | sort -u)" -- "$cur"))
      fi
      ;;
  esac
}

_gdos() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  case $prev in
    --host-file) _rack_files '*.@(yaml|yml)'; return ;;
    --key-file|--record|--replay) _rack_files; return ;;
    --level) _rack_words "print error warning info detail"; return ;;
    --lcm|--channel|--component|--count|--duration|--grep|--host) return ;;
  esac
  _rack_words "--lcm --channel --host-file --key-file --level --component --host --grep --count --duration
               --json --color --no-color --record --replay --silent --help --version"
}

_rack_gui() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  case $prev in
    --host-file) _rack_files '*.@(yaml|yml)'; return ;;
    --key-file|--map|--backtrace|--rackd) _rack_files; return ;;
    --web|--reports|--map-root|--config) COMPREPLY=($(compgen -d -- "$cur")); compopt -o filenames 2>/dev/null; return ;;
    --address|--port|--lcm|--gdos-lcm|--gdos-channel|--poll-ms|--timeout-ms|--forget-s|--max-clients) return ;;
  esac
  _rack_words "--address --port --lcm --host-file --key-file --web --map --map-root --reports --backtrace
               --gdos-lcm --gdos-channel --config --rackd --poll-ms --timeout-ms --forget-s --max-clients --help --version"
}

_rack_backtrace() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  case $prev in
    --root) COMPREPLY=($(compgen -d -- "$cur")); compopt -o filenames 2>/dev/null; return ;;
    --component|--file|--function|--reason|--task) return ;;
  esac
  if [[ $cur == -* ]]; then
    _rack_words "--summary --reason --component --task --function --file --root --help --version"
  else
    _rack_files
  fi
}

_rack_devsim() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  if ((COMP_CWORD == 1)); then
    _rack_words "gps cia402 hokuyo sick joystick --help --version"
    return
  fi
  case $prev in
    --link|--socket|--fifo) _rack_files; return ;;
    --fault) _rack_words "none checksum garbage truncated silent"; return ;;
  esac
  [[ $cur == -* ]] || return
  case ${COMP_WORDS[1]} in
    gps) _rack_words "--link --rate --lat --lon --alt --speed --course --fault --duration --help" ;;
    cia402) _rack_words "--socket --can --nodes --duration --help" ;;
    hokuyo) _rack_words "--link --rpm --front --side --fault --duration --help" ;;
    sick) _rack_words "--port --fault --duration --help" ;;
    joystick) _rack_words "--fifo --forward --turn --deadman --period-ms --duration --help" ;;
  esac
}

_rack_foxglove() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}
  if ((COMP_CWORD == 1)) && [[ $cur != -* ]]; then
    _rack_words "play"
    return
  fi
  if [[ ${COMP_WORDS[1]} == play ]]; then
    case $prev in
      play) _rack_files '*.mcap'; return ;;
      --gui|--speed|--topics|--init-mcl|--init-sigma-xy|--init-sigma-phi|--wait) return ;;
    esac
    _rack_words "--gui --speed --topics --init-mcl --init-sigma-xy --init-sigma-phi --wait --help"
    return
  fi
  case $prev in
    --record) _rack_files '*.mcap'; return ;;
    --compression) _rack_words "zstd lz4 none"; return ;;
    --gui|--port|--host|--topics|--duration|--period-ms) return ;;
  esac
  _rack_words "--gui --port --host --no-server --record --topics --compression --period-ms --polled --duration
               --help --version"
}

complete -F _rackd rackd
complete -F _rackctl rackctl
complete -F _gdos gdos
complete -F _rack_gui rack-gui
complete -F _rack_backtrace rack-backtrace
complete -F _rack_devsim rack-devsim
complete -F _rack_foxglove rack-foxglove
