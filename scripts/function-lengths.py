#!/usr/bin/env python3
"""Lists the functions of the product (config/ process/ capture/ sim/ rig/) by length.

A function is a brace block opened at namespace depth (outside any class, struct, enum or
lambda) whose head ends in ')' (with const/override/noexcept/-> T after it); lambdas and
member functions inside a class body count as part of what holds them. Lines are counted
from the head's first line to the closing brace.

  function-lengths.py [ROOT] [--over N] [--fail-over M] [--most K]
prints every function over N lines (default 100), longest first; exits 1 if any is over M.
"""
import os
import re
import sys

ROOTS = ("config", "process", "capture", "sim", "rig")


def strip_code(text):
    """Blanks comments, strings and chars (keeping newlines) so braces can be counted."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i)); i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c); i += 1; continue
            end = ")" + m.group(1) + '"'
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(" " * (min(j, n - 1) - i + 1)); i = j + 1
        else:
            out.append(c); i += 1
    return "".join(out)


HEAD_END = re.compile(r"\)\s*(const\s*)?(noexcept\s*)?(override\s*)?(final\s*)?(->\s*[\w:<>,\s*&]+)?$")
CONTROL = re.compile(r"^\s*(if|for|while|switch|catch|return|else)\b")


def functions(path):
    code = strip_code(open(path, encoding="utf-8", errors="replace").read())
    lines = code.split("\n")
    stack = []  # kinds of open braces: 'ns', 'class', 'fn', 'other'
    found = []
    start_line = {}
    pending = ""  # text since the last ; { or } at the current level
    pending_line = 0
    for ln, line in enumerate(lines, 1):
        for ch in line:
            if ch == "{":
                head = pending.strip()
                in_fn = any(k in ("fn", "class_fn") for k in stack)
                if in_fn:
                    kind = "other"
                elif re.search(r"\b(namespace)\b[^()]*$", head) or head.startswith('extern "C"'):
                    kind = "ns"
                elif re.search(r"\b(class|struct|union|enum)\b[^()]*$", head) and not HEAD_END.search(head):
                    kind = "class"
                elif HEAD_END.search(head) and not CONTROL.match(head) and "=" not in head.split("(")[0]:
                    kind = "fn" if not any(k == "class" for k in stack) else "class_fn"
                else:
                    kind = "other"
                if kind in ("fn", "class_fn"):
                    name = re.sub(r"\s+", " ", head.split("(")[0]).split(" ")[-1]
                    start_line[len(stack)] = (pending_line or ln, name)
                stack.append(kind)
                pending, pending_line = "", 0
            elif ch == "}":
                kind = stack.pop() if stack else "other"
                if kind in ("fn", "class_fn"):
                    first, name = start_line.pop(len(stack))
                    found.append((ln - first + 1, name, first))
                pending, pending_line = "", 0
            elif ch == ";":
                pending, pending_line = "", 0
            else:
                if not pending.strip() and not ch.isspace():
                    pending_line = ln
                pending += ch
        pending += " "
    return found


def main(argv):
    root, over, fail_over, most = ".", 100, None, 0
    args = list(argv)
    while args:
        a = args.pop(0)
        if a == "--over": over = int(args.pop(0))
        elif a == "--fail-over": fail_over = int(args.pop(0))
        elif a == "--most": most = int(args.pop(0))
        else: root = a
    rows = []
    for top in ROOTS:
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for f in files:
                if f.endswith((".cc", ".h", ".cpp")):
                    p = os.path.join(dirpath, f)
                    for length, name, line in functions(p):
                        rows.append((length, os.path.relpath(p, root), line, name))
    rows.sort(reverse=True)
    shown = [r for r in rows if r[0] > over]
    for length, p, line, name in (shown[:most] if most else shown):
        print(f"{length:5d}  {p}:{line}  {name}")
    print(f"function-lengths: {len(rows)} functions, {len(shown)} over {over} lines")
    if fail_over is not None:
        bad = [r for r in rows if r[0] > fail_over]
        if bad:
            print(f"function-lengths: {len(bad)} over {fail_over} lines")
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
