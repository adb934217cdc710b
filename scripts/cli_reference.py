#!/usr/bin/env python3
"""cli_reference.py: docs/cli.md's generated option lists, from the commands themselves.

A block in docs/cli.md of the form

    <!-- generated: crease gdsr train --help -->
    ```text
    ...
    ```

holds exactly what that command prints: its help comes from the command's option table
(src/cli/cli.h, cli_parse_documented), so the reference and --help cannot drift apart.

    python3 scripts/cli_reference.py build/release/crease          # rewrite the blocks
    python3 scripts/cli_reference.py build/release/crease --check  # exit 1 naming a stale one
"""
import difflib
import os
import re
import subprocess
import sys

MARK = re.compile(r"^<!-- generated: crease (.+) -->$")


def main():
    if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(sys.argv) >= 2 else 2
    crease, check = sys.argv[1], "--check" in sys.argv[2:]
    doc = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "cli.md")
    lines = open(doc, encoding="utf-8").read().split("\n")
    out, i, stale, blocks = [], 0, [], 0
    while i < len(lines):
        out.append(lines[i])
        m = MARK.match(lines[i])
        i += 1
        if not m:
            continue
        blocks += 1
        if i >= len(lines) or lines[i] != "```text":
            sys.exit(f"{doc}:{i + 1}: a generated block opens with ```text")
        end = i + 1
        while end < len(lines) and lines[end] != "```":
            end += 1
        if end == len(lines):
            sys.exit(f"{doc}:{i + 1}: the generated block never closes")
        run = subprocess.run([crease] + m.group(1).split(), capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"{doc}:{i}: 'crease {m.group(1)}' exited {run.returncode}")
        want = run.stdout.rstrip("\n").split("\n")
        have = lines[i + 1:end]
        if have != want:
            stale.append(m.group(1))
            if check:
                sys.stdout.writelines(difflib.unified_diff(
                    [h + "\n" for h in have], [w + "\n" for w in want],
                    f"docs/cli.md: crease {m.group(1)}", "the command's output"))
        out += ["```text"] + want + ["```"]
        i = end + 1
    if blocks == 0:
        sys.exit(f"{doc}: no generated block")
    if check:
        if stale:
            print("stale in docs/cli.md (rewrite with scripts/cli_reference.py CREASE): "
                  + ", ".join(stale))
            return 1
        return 0
    tmp = f"{doc}.tmp.{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write("\n".join(out))
    os.replace(tmp, doc)
    print(f"docs/cli.md: {blocks} blocks, {len(stale)} rewritten")
    return 0


if __name__ == "__main__":
    sys.exit(main())
