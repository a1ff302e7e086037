"""Wall-clock and CPU seconds measured together.

Wall-clock time is what a user waits for, but on a shared machine it also counts the
time other processes held the cores. The CPU seconds of this process do not, so ratios
of times measured at different moments (a perturbed world's cell against the nominal
one's, run while other cells shared the machine) compare like with like.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


@dataclass
class Stopwatch:
    """Accumulates the wall-clock and CPU (this process, all threads) seconds of every
    :meth:`running` block."""

    wall: float = 0.0
    cpu: float = 0.0

    @contextmanager
    def running(self) -> Iterator[None]:
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.wall += time.perf_counter() - wall
            self.cpu += time.process_time() - cpu
