#!/usr/bin/env python3
"""Count a command's trip through the top-level modules of src/, from a call tree written
by reading the code (docs/data/scan-steps-trip.md holds the trees of `scan steps`).

A tree has one call a line, `module::function`, indented two spaces a level below its
caller. It lists, depth first, the calls that are given the command's arguments or what
carries them on (the parsed flags, the plan, the scan setup, a point's run spec or
request, the sampling criterion), each function once: a function reached again is not
listed again (the arguments already passed through it). The trip starts in the first
line's module, walks down into each call and back up when it returns; this prints

  modules   the top-level modules it enters
  moves     the steps from one module to another (calls and returns)
  returns   returns to a higher layer (a call into a lower module coming back)
  visits    how many separate times the trip is in each module (cli first)

    scripts/trip_count.py TREE_FILE [SECTION]

SECTION picks the fenced block (```trip NAME) of that name in a Markdown file.
"""

import sys

LAYERS = ["error", "units", "expr", "plot", "settings", "forces", "split", "system",
          "integrators", "io", "run", "analysis", "studies", "cli"]


def read_tree(path, section):
    lines = open(path, encoding="utf-8").read().splitlines()
    if section is not None:
        start = lines.index(f"```trip {section}") + 1
        end = lines.index("```", start)
        lines = lines[start:end]
    calls = []
    for line in lines:
        if not line.strip() or line.strip().startswith("#"):
            continue
        depth = (len(line) - len(line.lstrip(" "))) // 2
        name = line.strip().split()[0]
        module = name.split("::")[0]
        if module not in LAYERS:
            sys.exit(f"unknown top-level module in `{name}`")
        calls.append((depth, module, name))
    return calls


def walk(calls):
    """The sequence of modules the trip is in, one entry per step."""
    sequence = [calls[0][1]]
    stack = [calls[0][1]]
    for depth, module, _ in calls[1:]:
        while len(stack) > depth:
            stack.pop()
            sequence.append(stack[-1])
        stack.append(module)
        sequence.append(module)
    while len(stack) > 1:
        stack.pop()
        sequence.append(stack[-1])
    return sequence


def main():
    path = sys.argv[1]
    section = sys.argv[2] if len(sys.argv) > 2 else None
    sequence = walk(read_tree(path, section))
    trip = [m for i, m in enumerate(sequence) if i == 0 or m != sequence[i - 1]]
    rank = {m: i for i, m in enumerate(LAYERS)}
    moves = len(trip) - 1
    returns = sum(1 for a, b in zip(trip, trip[1:]) if rank[b] > rank[a])
    visits = {}
    for m in trip:
        visits[m] = visits.get(m, 0) + 1
    print(f"modules  {len(visits)}: {' '.join(sorted(visits, key=lambda m: -rank[m]))}")
    print(f"moves    {moves}")
    print(f"returns  {returns} to a higher layer")
    print("visits   " + ", ".join(f"{m} {n}" for m, n in
                                  sorted(visits.items(), key=lambda kv: -rank[kv[0]])))


if __name__ == "__main__":
    main()
