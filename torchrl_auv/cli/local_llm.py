"""Serve SmolLM2-135M on 127.0.0.1 with an OpenAI-compatible API (the ``local-llm`` extra).

python -m torchrl_auv.cli.local_llm --port 8080
"""

from __future__ import annotations

import argparse
import subprocess

from torchrl_auv.advisor.local_llm import server_command


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Serve SmolLM2-135M on 127.0.0.1 (OpenAI API)")
    parser.add_argument("--port", type=int, default=8080)
    parser.add_argument("--model", default=None, help="another GGUF file (default: SmolLM2)")
    args = parser.parse_args(argv)
    command = server_command(args.model, port=args.port)
    print(f"serving on http://127.0.0.1:{args.port}/v1 as model 'smollm2'", flush=True)
    raise SystemExit(subprocess.call(command))


if __name__ == "__main__":
    main()
