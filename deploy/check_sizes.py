#!/usr/bin/env python3
"""Checks the size limits of STYLE.md: no source file over 500 lines, no function over 80.

Usage: deploy/check_sizes.py [--max-file N] [--max-function N] [PATH...]
Checks the tracked .h/.cpp/.cc files of the source folders (or the PATHs given). A function's
length is counted as clang-tidy's readability-function-size LineThreshold counts it: the line of
its closing brace minus the line of its opening brace. Lambdas and local classes count toward the
function that holds them. Functions are found lexically (comments, strings and preprocessor lines
removed, then braces matched), which needs no build and no compiler flags.
Exceptions: deploy/size_exceptions.txt, one `path` or `path:function` a line with its owner;
an exception that no longer matches a violation is itself reported, so the list only shrinks.
"""
import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("proto", "transport", "slam", "certify", "actors", "bin", "tests")
EXCEPTIONS = ROOT / "deploy" / "size_exceptions.txt"

SCOPE_HEAD = re.compile(r"^\s*(?:(?:inline\s+)?namespace\b|class\b|struct\b|union\b|enum\b|extern\b)")
CONTROL_HEAD = re.compile(r"^\s*(?:if|for|while|switch|catch|do|else|try)\b")
CTOR_INIT = re.compile(r"\)\s*(?:noexcept\s*)?:[^:]")
TEST_MACRO = re.compile(r"^\s*(TEST(?:_F|_P)?\s*\([^)]*\))")


def strip_code(text):
    """Returns `text` with comments, string/char literals and preprocessor lines blanked, keeping
    every newline so line numbers stay."""
    out = []
    i, n = 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c == "#":
            # A preprocessor directive, with its backslash continuations.
            while i < n and not (text[i] == "\n" and text[i - 1] != "\\"):
                out.append("\n" if text[i] == "\n" else " ")
                i += 1
            continue
        if c == "/" and text.startswith("//", i):
            while i < n and text[i] != "\n":
                i += 1
            continue
        if c == "/" and text.startswith("/*", i):
            end = text.find("*/", i + 2)
            end = n if end < 0 else end + 2
            out.append("".join(ch if ch == "\n" else " " for ch in text[i:end]))
            i = end
            continue
        raw = re.match(r'R"([^(\s]{0,16})\(', text[i:i + 20]) if c == "R" else None
        if raw and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            close = ")" + raw.group(1) + '"'
            end = text.find(close, i + raw.end())
            end = n if end < 0 else end + len(close)
            out.append('""' + "".join("\n" for ch in text[i:end] if ch == "\n"))
            i = end
            continue
        if c in "\"'":
            if c == "'" and i > 0 and text[i - 1].isalnum():  # digit separator 1'000
                out.append(" ")
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
            continue
        if c == "\n":
            line_start = True
        elif not c.isspace():
            line_start = False
        out.append(c)
        i += 1
    return "".join(out)


def without_template_prefix(head):
    """`head` without leading `template <...>` clauses."""
    while True:
        m = re.match(r"\s*template\s*<", head)
        if not m:
            return head
        depth, k = 1, m.end()
        while k < len(head) and depth:
            depth += {"<": 1, ">": -1}.get(head[k], 0)
            k += 1
        head = head[k:]


def classify(head):
    """What an opening brace preceded by `head` (text since the last ; { or } at its level)
    opens at namespace or class scope: "scope", "function", "init" (a brace initialiser in a
    constructor's member-initialiser list) or "block" (any other initialiser)."""
    head = without_template_prefix(head)
    if SCOPE_HEAD.match(head):
        return "scope"
    if ")" not in head or CONTROL_HEAD.match(head) or re.search(r"=\s*$|\breturn\b", head):
        return "block"
    if CTOR_INIT.search(head) and re.search(r"[\w>]\s*$", head):
        return "init"
    return "function"


def functions(text):
    """Yields (name, first_line, body_lines) for each function body at namespace or class scope."""
    code = strip_code(text)
    stack = []  # per open brace: (kind, head, offset)
    head_start = 0  # where the text that precedes the next brace begins
    for i, c in enumerate(code):
        at_scope = not stack or stack[-1][0] == "scope"
        if c == ";" and at_scope:
            head_start = i + 1
        elif c == "{":
            if not at_scope:
                stack.append(("block", "", i))
                continue
            head = code[head_start:i]
            kind = classify(head)
            stack.append((kind, head, i))
            if kind != "init":
                head_start = i + 1
        elif c == "}" and stack:
            kind, head, open_at = stack.pop()
            if kind == "init":
                continue
            if kind == "function":
                open_line = code.count("\n", 0, open_at) + 1
                close_line = code.count("\n", 0, i) + 1
                yield function_name(head), open_line, close_line - open_line
            if not stack or stack[-1][0] == "scope":
                head_start = i + 1


def function_name(head):
    """The qualified name before the parameter list of a function head."""
    head = without_template_prefix(head)
    test = TEST_MACRO.match(head)
    if test:
        return re.sub(r"\s+", "", test.group(1))
    op = re.search(r"operator\s*\(\s*\)", head)
    cut = op.end() if op else head.find("(")
    before = head[:cut] if cut >= 0 else head
    if op:
        before = before.replace(" ", "")
        return re.search(r"[\w:~<>]*operator\(\)$", before).group(0)
    match = re.search(r"((?:\w+\s*(?:<[^<>]*>)?\s*::\s*)*~?(?:operator\s*\S+|\w+))\s*$", before)
    return re.sub(r"\s+", "", match.group(1)) if match else "?"


def tracked_sources(paths):
    if paths:
        files = []
        for p in paths:
            p = Path(p)
            files += [q for q in p.rglob("*") if q.suffix in (".h", ".cpp", ".cc")] if p.is_dir() \
                else [p]
        return [f.resolve().relative_to(ROOT).as_posix() for f in files]
    out = subprocess.run(["git", "ls-files", "*.h", "*.cpp", "*.cc"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout.split()
    return [f for f in out if f.split("/")[0] in FOLDERS and (ROOT / f).exists()]


def read_exceptions():
    allowed = {}
    if EXCEPTIONS.exists():
        for line in EXCEPTIONS.read_text().splitlines():
            line = line.split("#")[0].strip()
            if line:
                key, _, owner = line.partition(" ")
                allowed[key] = owner.strip()
    return allowed


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-file", type=int, default=500)
    parser.add_argument("--max-function", type=int, default=80)
    parser.add_argument("paths", nargs="*")
    args = parser.parse_args()
    allowed = read_exceptions()
    used = set()
    violations = []
    for rel in tracked_sources(args.paths):
        text = (ROOT / rel).read_text(errors="replace")
        lines = text.count("\n") + (0 if text.endswith("\n") else 1)
        if lines > args.max_file:
            violations.append((rel, f"{rel}: {lines} lines (limit {args.max_file})"))
        for name, line, length in functions(text):
            if length > args.max_function:
                violations.append((f"{rel}:{name}", f"{rel}:{line}: function {name} has {length} "
                                   f"lines (limit {args.max_function})"))
    failed = 0
    for key, message in violations:
        file_key = key.split(":")[0]
        if key in allowed or file_key in allowed:
            used.add(key if key in allowed else file_key)
            print(f"allowed ({allowed.get(key) or allowed.get(file_key)}): {message}")
        else:
            print(message)
            failed += 1
    if not args.paths:
        for key in sorted(set(allowed) - used):
            print(f"{EXCEPTIONS.relative_to(ROOT)}: '{key}' is within the limits now: remove it")
            failed += 1
    print(f"check_sizes: {failed} violation(s)" if failed else "check_sizes: ok")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
