"""Progress of long calls: tqdm bars, or plain lines on a terminal without tqdm."""

from __future__ import annotations

import sys
from typing import Any, Callable, Optional, Union

#: ``callback(stage, done, total)``: the stage's name, units done, units in all (0: unknown).
ProgressCallback = Callable[[str, int, int], Any]


class _Bars:
    """One tqdm bar per stage (``tqdm.auto``: text bars, or widgets in a notebook)."""

    def __init__(self, tqdm: Any) -> None:
        self._tqdm = tqdm
        self._bar: Any = None
        self._stage: Optional[str] = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self._stage:
            self.close()
            self._stage = stage
            self._bar = self._tqdm(total=total or None, desc=stage, unit="", leave=False)
        if self._bar is not None:
            self._bar.update(done - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class _Lines:
    """Without tqdm: a line per stage on stderr when it is a terminal."""

    def __init__(self) -> None:
        self._stage: Optional[str] = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self._stage:
            self._stage = stage
            print(f"froctomap: {stage} ({total} steps)", file=sys.stderr, flush=True)

    def close(self) -> None:
        pass


def reporter(progress: Union[bool, ProgressCallback, None]) -> Optional[ProgressCallback]:
    """The callback for a ``progress=`` argument: ``True`` draws bars, ``False``/``None``
    reports nothing, a callable is called as ``progress(stage, done, total)``."""
    if progress is None or progress is False:
        return None
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            return _Lines() if sys.stderr is not None and sys.stderr.isatty() else None
        return _Bars(tqdm)
    if callable(progress):
        return progress
    raise TypeError("progress must be True, False, None or a callable(stage, done, total)")


def close(callback: Optional[ProgressCallback]) -> None:
    """Ends the bars of a callback made by ``reporter``."""
    closer = getattr(callback, "close", None)
    if isinstance(callback, (_Bars, _Lines)) and closer is not None:
        closer()
