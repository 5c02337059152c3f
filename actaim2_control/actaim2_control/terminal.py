"""Single keys from a terminal, without Enter: the keyboard of ``teleop_node``.

The terminal goes into cbreak mode (no line buffering, no echo; Ctrl-C still sends SIGINT)
for as long as the context is open, and is restored on every way out, exceptions included.
"""
from __future__ import annotations

import os
import select
import termios
import tty
from typing import TextIO

BACKSPACES = (b"\x7f", b"\x08")
LINE_ENDS = (b"\r", b"\n")


class NotATerminal(RuntimeError):
    pass


class KeyboardTerminal:
    """``with KeyboardTerminal(sys.stdin, sys.stdout) as keys: keys.read_key(0.1)``."""

    def __init__(self, stdin: TextIO, stdout: TextIO):
        if not stdin.isatty():
            raise NotATerminal("standard input is not a terminal: teleop_node reads single keys from one "
                               "(start it in a terminal: ros2 run actaim2_control teleop_node)")
        self._fd = stdin.fileno()
        self._out = stdout
        self._saved: list | None = None

    def __enter__(self) -> "KeyboardTerminal":
        self._saved = termios.tcgetattr(self._fd)
        tty.setcbreak(self._fd)
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is not None:
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)

    def write(self, text: str) -> None:
        self._out.write(text if text.endswith("\n") else text + "\n")
        self._out.flush()

    def read_key(self, timeout: float) -> str | None:
        """One key (a character), or None when none arrives within ``timeout`` s."""
        ready, _, _ = select.select([self._fd], [], [], timeout)
        if not ready:
            return None
        first = os.read(self._fd, 1)
        if not first:
            raise EOFError("the terminal closed")
        data = first + self._continuation(first)
        return data.decode("utf-8", errors="replace")

    def read_line(self, prompt: str) -> str:
        """A line typed by the operator (echoed, backspace works), up to Enter."""
        self._out.write(prompt)
        self._out.flush()
        line = b""
        while True:
            byte = os.read(self._fd, 1)
            if not byte:
                raise EOFError("the terminal closed")
            if byte in LINE_ENDS:
                self._out.write("\n")
                self._out.flush()
                return line.decode("utf-8", errors="replace")
            if byte in BACKSPACES:
                if line:
                    line = line[:-1]
                    while line and (line[-1] & 0xC0) == 0x80:  # the rest of a multi-byte character
                        line = line[:-1]
                    self._out.write("\b \b")
            else:
                char = byte + self._continuation(byte)
                line += char
                self._out.write(char.decode("utf-8", errors="replace"))
            self._out.flush()

    def discard_typed(self) -> int:
        """Throw away keys typed while the arm was busy (they were meant for another moment)."""
        count = 0
        while select.select([self._fd], [], [], 0.0)[0]:
            count += len(os.read(self._fd, 1024))
        return count

    def _continuation(self, first: bytes) -> bytes:
        """The remaining bytes of a UTF-8 character that starts with ``first``."""
        if not first or first[0] < 0xC0:
            return b""
        extra = 1 if first[0] < 0xE0 else 2 if first[0] < 0xF0 else 3
        return os.read(self._fd, extra)
