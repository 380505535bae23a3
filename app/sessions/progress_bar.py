"""The commands' progress bar: tqdm that shows its final state once (a log gets one 100 % line, not three)."""
from __future__ import annotations

from tqdm import tqdm


class ProgressBar(tqdm):
    """tqdm whose step reaching `total` closes the bar, which shows the final state once; set the postfix with
    `refresh=False` before `update` (a refresh of its own would print another line in a log)."""

    def update(self, n: float = 1) -> bool | None:
        if self.total is not None and not self.disable and self.n + n >= self.total:
            self.n += n
            self.close()
            return True
        return super().update(n)
