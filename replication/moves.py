"""A record of pure moves, for results made under the earlier provenance scheme.

Until the layout of issue 16, a code hash covered each file's path and bytes, so moving a
module (and rewriting the imports that name it) changed the hash of every runner that
reached it. Since then it covers what each file's code does, without imports, docstrings
or paths (:func:`replication.provenance.code_text`): a pure move changes nothing.

Results recorded before carry hashes of the earlier scheme. Re-running them proves
nothing new when the move was pure, and the documented sweeps take most of an hour, so
this module checks purity instead and records it::

    python -m replication.moves BEFORE_COMMIT

For every experiment config it computes, on a checkout of ``BEFORE_COMMIT``, the runner's
hash under the earlier scheme and under the current one, and, on the working tree, the
current-scheme hash of the (moved) runner. When the two current-scheme hashes are equal, no
code the runner reaches changed except its imports and paths: the record maps the earlier
hash to the current one (``results/provenance-moves.json``). :func:`replication.provenance.
accepted_code_hashes` then counts a result with the earlier hash as made by the current
code, for as long as the code keeps the recorded current hash.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from replication.provenance import MOVES_RECORD, PROJECT_ROOT, code_hash

_HASHES = ("import json, sys; from replication.provenance import code_hash; "
           "print(json.dumps({r: code_hash(r) for r in json.loads(sys.argv[1])}))")


def _runners(root):
    """``{experiment: runner}`` of the experiment configs under ``root``."""
    found = {}
    for path in sorted((root / "configs" / "experiment").glob("*.yaml")):
        for line in path.read_text().splitlines():
            if line.startswith("runner:"):
                found[path.stem] = line.split(":", 1)[1].split("#")[0].strip()
    return found


def _hashes_in(tree, runners):
    out = subprocess.run([sys.executable, "-c", _HASHES, json.dumps(sorted(set(runners)))],
                         cwd=tree, capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(tree), "PATH": ""})
    return json.loads(out.stdout)


def record(before):
    """The record of runners whose code moved purely since commit ``before``."""
    with tempfile.TemporaryDirectory() as folder:
        tree = Path(folder) / "before"
        subprocess.run(["git", "worktree", "add", "--detach", str(tree), before],
                       cwd=PROJECT_ROOT, check=True, capture_output=True)
        try:
            old = _runners(tree)
            legacy = _hashes_in(tree, old.values())
            shutil.copy(PROJECT_ROOT / "replication" / "provenance.py",
                        tree / "replication" / "provenance.py")
            before_now = _hashes_in(tree, old.values())
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)],
                           cwd=PROJECT_ROOT, check=True, capture_output=True)
    new = _runners(PROJECT_ROOT)
    moves, changed = {}, []
    for name, runner in sorted(new.items()):
        if name not in old:
            continue
        now = code_hash(runner)
        if before_now[old[name]] != now:
            changed.append(name)
            continue
        moves[runner] = {"legacy_runner": old[name],
                         "legacy_code_sha256": legacy[old[name]], "code_sha256": now}
    return {"before": before, "runners": moves, "not_pure": changed}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", help="the commit before the move")
    args = parser.parse_args(argv)
    known = subprocess.run(["git", "rev-parse", "--verify", "--quiet",
                            f"{args.before}^{{commit}}"], cwd=PROJECT_ROOT,
                           capture_output=True, text=True)
    if known.returncode != 0:
        print(f"error: {args.before}: not a commit of this repository; expected the commit "
              "before the move (git log)", file=sys.stderr)
        return 2
    result = record(args.before)
    MOVES_RECORD.write_text(json.dumps(result, indent=1) + "\n")
    print(f"{len(result['runners'])} runners moved purely; not pure: "
          f"{', '.join(result['not_pure']) or 'none'} -> {MOVES_RECORD}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
