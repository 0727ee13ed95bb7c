"""The command lines README.md and docs/*.md show (issue 57), and the argument lists a synopsis stands
for. Used by test_doc_commands.py.

A command line is a line of a fenced code block, or of an indented code block, that starts with
``hbrdf``, ``hbrdf-codegen``, ``python bench/``, ``python scripts/``, ``python -m`` (or ``python3``,
or ``torchrun ... --no-python hbrdf``), after ``VAR=value`` assignments and ``/usr/bin/time -v``, and
before a ``#`` comment;
a trailing backslash or a more deeply indented next line continues it; ``a && b`` is two lines.

A *synopsis* shows the shape of a command rather than one to run: ``[optional]`` groups,
``(a | b)`` and ``x|y`` alternatives, ``SOURCE...`` repetition, CAPITALISED placeholders. It
stands for a few argument lists (:func:`expand`): the minimal one (every optional group left out)
and the maximal ones (every optional group in, the k-th alternative of each choice), with each
placeholder replaced by a value of its kind (``PLACEHOLDERS``).
"""

from __future__ import annotations

import pathlib
import re
import shlex
from typing import Dict, List, Tuple

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
FENCE = re.compile(r"^ *(```|~~~)[^\n]*\n(.*?)^ *\1 *$", re.S | re.M)
COMMAND = re.compile(r"^(?:[A-Z_]+=\S+\s+)*(?:/usr/bin/time -v\s+)?"
                     r"(?:hbrdf(?:-codegen)?\s|python3? (?:bench/|scripts/|-m\s)|torchrun\s)")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _code_blocks(text: str) -> List[Tuple[int, List[str]]]:
    """[(first line number, lines)] of the fenced blocks and of the indented blocks (four spaces
    after a blank line, outside fences) of a Markdown text."""
    blocks, fenced = [], set()
    for m in FENCE.finditer(text):
        first = text.count("\n", 0, m.start(2)) + 1
        lines = m.group(2).splitlines()
        blocks.append((first, lines))
        fenced.update(range(first - 1, first + len(lines) + 1))
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if i not in fenced and _indent(lines[i]) >= 4 and lines[i].strip() and (i == 0 or not lines[i - 1].strip()):
            j = i
            while j < len(lines) and j not in fenced and (not lines[j].strip() or _indent(lines[j]) >= 4):
                j += 1
            blocks.append((i + 1, lines[i:j]))
            i = j
        else:
            i += 1
    return blocks


def _strip_comment(line: str) -> str:
    """The line without its ``#`` comment (a ``#`` after whitespace, outside quotes)."""
    quote = None
    for k, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (k == 0 or line[k - 1].isspace()):
            return line[:k].rstrip()
    return line.rstrip()


def documented_commands() -> List[Tuple[str, str]]:
    """[(file:line, command)] of every command line of the documents, in order, each on one line."""
    out = []
    for doc in DOCS:
        for first, lines in _code_blocks(doc.read_text()):
            i = 0
            while i < len(lines):
                line = lines[i]
                text, start = _strip_comment(line.strip()), i
                while i + 1 < len(lines) and (text.endswith("\\") or (lines[i + 1].strip() and _indent(
                        lines[i + 1]) > _indent(line) and not COMMAND.match(lines[i + 1].strip()))):
                    i += 1
                    text = text.rstrip("\\").rstrip() + " " + _strip_comment(lines[i].strip())
                for part in text.split(" && "):
                    if COMMAND.match(part.strip()):
                        out.append((f"{doc.relative_to(ROOT)}:{first + start}", part.strip()))
                i += 1
    return out


# ---- synopses ------------------------------------------------------------------------------------

#: Words in a synopsis that stand for "and other flags": left out of every argument list.
FILLERS = {"...", "flags"}


def is_synopsis(command: str, placeholders: Dict[str, str]) -> bool:
    words = re.findall(r"[A-Za-z_][\w.]*", command)
    return (any(c in command for c in "[]()") or "..." in command or re.search(r"\S\|\S| \| ", command) is not None
            or any(w in placeholders for w in words))


def _tokens(command: str) -> List[str]:
    """Shell words, with the synopsis brackets and spaced bars as tokens of their own."""
    spaced = re.sub(r"([\[\]()])", r" \1 ", command)
    return shlex.split(spaced)


def _parse_group(tokens: List[str], i: int, close: str):
    """(alternatives, next index): each alternative a list of items; an item is a word or
    ("opt" | "req", alternatives)."""
    alternatives, current = [], []
    while i < len(tokens) and tokens[i] != close:
        t = tokens[i]
        if t in ("[", "("):
            inner, i = _parse_group(tokens, i + 1, "]" if t == "[" else ")")
            current.append(("opt" if t == "[" else "req", inner))
        elif t == "|":
            alternatives.append(current)
            current = []
        else:
            current.append(t)
        i += 1
    alternatives.append(current)
    return alternatives, i


def _choose(items, k: int, maximal: bool) -> List[str]:
    words = []
    for item in items:
        if isinstance(item, str):
            word = item[:-3] if item.endswith("...") and item != "..." else item  # SOURCE... -> one SOURCE
            if word in FILLERS:
                continue
            choices = word.split("|") if re.fullmatch(r"[^|=]+(\|[^|=]+)+", word) else [word]  # glsl|hlsl
            if "=" in word and "|" in word:  # K=A|B: choices of the value
                key, value = word.split("=", 1)
                choices = [f"{key}={v}" for v in value.split("|")]
            words.append(choices[min(k, len(choices) - 1)])
        else:
            kind, alternatives = item
            if (kind == "opt" and not maximal) or (alternatives[0][:1] == ["..."] and len(alternatives) == 1):
                continue  # left out; [... prose] says "other flags"
            words += _choose(alternatives[k % len(alternatives)], k, maximal)
    return words


def _substitute(word: str, placeholders: Dict[str, str]) -> str:
    if word in placeholders:
        return placeholders[word]
    if "=" in word and not word.startswith("-"):
        return "=".join(_substitute(part, placeholders) for part in word.split("=", 1))
    return word


def _widest(items) -> int:
    """The largest number of alternatives of any choice in ``items``."""
    counts = [1]
    for item in items:
        if isinstance(item, str):
            counts.append(len(item.split("=", 1)[-1].split("|")))
        else:
            counts.append(len(item[1]))
            counts += [_widest(a) for a in item[1]]
    return max(counts)


def expand(command: str, placeholders: Dict[str, str]) -> List[List[str]]:
    """The argument lists (shell words, the program's name first) a synopsis stands for: the
    minimal one, then the maximal one for each alternative index k (duplicates removed)."""
    tokens = _tokens(command)
    alternatives, _ = _parse_group(tokens, 0, None)
    assert len(alternatives) == 1, f"{command}: a top-level '|' (put the alternatives in parentheses)"
    items = alternatives[0]
    widest = _widest(items)
    lists = []
    for k, maximal in [(0, False)] + [(k, True) for k in range(widest)]:
        words = [_substitute(w, placeholders) for w in _choose(items, k, maximal)]
        if words not in lists:
            lists.append(words)
    return lists
