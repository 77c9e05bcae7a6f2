"""A peer simulator running as a subprocess of its own venv's Python, talking JSON lines."""

from __future__ import annotations

import json
import subprocess
from typing import Any

__all__ = ["PeerProcess"]


class PeerProcess:
    """Base of the peers' subprocesses: ``self.proc`` answers each request with a JSON line."""

    proc: subprocess.Popen

    def answer(self, key: str) -> dict[str, Any]:
        """The next JSON line on the peer's stdout that has ``key``; RuntimeError with its stderr
        when it ends first."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:  # the peer may print its own lines first
            if line.startswith("{"):
                msg = json.loads(line)
                if key in msg:
                    return msg
        err = self.proc.stderr.read() if self.proc.stderr else ""
        raise RuntimeError(f"peer subprocess ended: {err.strip()[-2000:]}")

    def close(self) -> None:
        """Ask the peer to quit (kill it after 30 s)."""
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write(json.dumps({"op": "quit"}) + "\n")
                self.proc.stdin.close()
                self.proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
