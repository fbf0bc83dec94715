"""``.. example-run::``: run an example script while the docs build and show what it printed.

The directive's argument is the command line (a path under the repository root, then its
arguments); ``:figure:`` names a PNG the command writes (a path under the build's
``_example_figures``), shown below the output. A command that fails stops the build with its
output, so a tutorial never shows a script that no longer runs.

    .. example-run:: examples/rollout_expert.py --steps 40 --out {figures}/expert.png
       :figure: expert.png
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import ClassVar

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 600


class ExampleRun(SphinxDirective):
    required_arguments = 1
    final_argument_whitespace = True
    option_spec: ClassVar[dict] = {"figure": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        figures = Path(self.env.app.srcdir) / "_example_figures"
        figures.mkdir(exist_ok=True)
        argv = shlex.split(self.arguments[0].format(figures=figures))
        shown = self.arguments[0].format(figures=".")
        env = {
            **os.environ,
            "OMP_NUM_THREADS": "1",
            "MKL_NUM_THREADS": "1",
            "WANDB_MODE": "offline",
            "PYTHONPATH": str(ROOT),
        }
        done = subprocess.run(
            [sys.executable, *argv],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
        )
        if done.returncode != 0:
            raise ExtensionError(
                f"{shown} exited with {done.returncode}:\n{done.stdout}\n{done.stderr}"
            )
        command = nodes.literal_block(text=f"$ python {shown}", language="console")
        printed = done.stdout.rstrip().replace(str(figures), ".") or "(no output)"
        out: list[nodes.Node] = [command, nodes.literal_block(text=printed, language="text")]
        if "figure" in self.options:
            name = self.options["figure"]
            if not (figures / name).is_file():
                raise ExtensionError(f"{shown} did not write the figure {name}")
            out.append(nodes.image(uri=f"/_example_figures/{name}", alt=name))
        return out


def setup(app):
    app.add_directive("example-run", ExampleRun)
    return {"parallel_read_safe": True, "version": "1"}
