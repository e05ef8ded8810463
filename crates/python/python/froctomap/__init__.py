"""froctomap: long-term 3D maps from Python.

A series of OctoMap snapshots (``.bt``/``.ot``) becomes one compact spatio-temporal
``.froct`` file (a FreMEn model per changing voxel, plus the outliers that make it exact).
From it you get the map as observed at any past time, bit for bit, and the predicted map at
any time; maps come out as OctoMap bytes (what the ``froctomap`` command line writes) or as
numpy arrays.

>>> import froctomap
>>> report = froctomap.build("office/", "office.froct")            # doctest: +SKIP
>>> f = froctomap.open("office.froct")                               # doctest: +SKIP
>>> f.times[:3]                                                      # doctest: +SKIP
array([1.4518656e+09, 1.4518674e+09, 1.4518692e+09])
>>> occupied, free = f.retrieve("2016-01-04T10:00:00Z").point_cloud()  # doctest: +SKIP
>>> later = f.predict("2016-02-01T10:00:00Z").to_ot_bytes()          # doctest: +SKIP

Every call that reads or writes files releases the interpreter while the Rust code works.
Failures raise :class:`FroctError` (an ``OSError`` and a ``ValueError``) with the command
line's message. See docs/PYTHON.md for a tour and docs/FLEET.md for many archives on Dask.
"""

from __future__ import annotations

import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Tuple, Union

from . import _progress
from ._errors import FroctError
from ._native import FroctFile, Map, __version__, open, parse_time
from . import _native
from ._progress import ProgressCallback

__all__ = [
    "FroctError",
    "FroctFile",
    "Map",
    "ProgressCallback",
    "__version__",
    "build",
    "evaluate",
    "open",
    "parse_time",
]

PathLike = Union[str, "os.PathLike[str]"]
#: One input, or several: directories (their manifest.csv, else every map file), glob
#: patterns, manifest CSV files, map files, ROS bags / MCAP files.
Inputs = Union[PathLike, Iterable[PathLike]]
#: Maps as ``.bt``/``.ot`` file contents with their times (Unix seconds, ISO 8601 text or a
#: datetime), for ``build``.
TimedMaps = Iterable[Tuple[Any, bytes]]


def _paths(inputs: Inputs) -> List[Any]:
    if isinstance(inputs, (str, bytes, os.PathLike)):
        return [inputs]
    return list(inputs)


def build(
    inputs: Union[Inputs, TimedMaps],
    output: PathLike,
    *,
    lossy: bool = False,
    order: Union[str, int] = "auto",
    progress: Union[bool, ProgressCallback, None] = True,
    model: str = "fremen-periods",
    model_options: Optional[Mapping[str, Any]] = None,
    max_order: Optional[int] = None,
    periods: Optional[Iterable[Union[str, float]]] = None,
    tile_depth: int = 10,
    zstd_level: int = 19,
    toggle_block: int = 256,
    skip_bad: bool = False,
    resolution: Optional[float] = None,
    allow_mostly_skipped: bool = False,
    tags: Optional[Mapping[str, Any]] = None,
    created: Any = None,
    memory: Optional[int] = None,
    tmp_dir: Optional[PathLike] = None,
    start: Any = None,
    step: Union[str, float, None] = None,
    times_file: Optional[PathLike] = None,
    times_from_names: bool = False,
    topic: Optional[str] = None,
    time_source: str = "header",
) -> Dict[str, Any]:
    """Builds one FROctomap file from a series of OctoMap snapshots (``froctomap build``).

    ``inputs``: directories (their ``manifest.csv``, else every ``.bt``/``.ot`` file in
    natural order), glob patterns, manifests (``path,time``), map files, recordings (ROS 1
    bags, MCAP files, ROS 2 bag directories; ``topic``, ``time_source="header"|"log"``),
    ``"-"`` (an MCAP stream on the process's standard input), or an iterable of
    ``(time, bytes)`` pairs: maps as ``.bt``/``.ot`` file contents with their times (any
    iterable, a generator too; each map is spooled to disk in ``tmp_dir`` or beside the
    output as it comes, so memory does not hold them).
    Times come from manifests or file names, or from ``start`` and ``step`` (``"10min"``,
    seconds), or one per line from ``times_file``; times without a zone are UTC.

    ``lossy=False`` keeps every observed state exactly; ``order`` is the number of periodic
    components per voxel or ``"auto"`` (chosen per voxel, up to ``max_order``). ``model``,
    ``model_options`` (``{"key": value}``) and ``periods`` (extra candidate periods, e.g.
    ``["1d", "8h"]``) choose the temporal model as ``--model``, ``--model-option`` and
    ``--periods`` do. ``created`` (a time) or ``SOURCE_DATE_EPOCH`` makes the file
    reproducible; ``memory`` (bytes, default 64 MiB) bounds the accumulated histories, which
    spill to ``tmp_dir`` (default: beside the output) beyond it. ``progress``: ``True`` draws
    a bar per stage (tqdm when installed), a callable is called as
    ``progress(stage, done, total)``, ``False`` reports nothing.

    The output is written atomically and is never one of the inputs. Returns the report of
    ``froctomap build --json`` as a dict (``file_bytes``, ``input_bytes``, ``used``,
    ``cells``, ``toggles``, ...). Raises :class:`FroctError` with the command line's message.
    """
    callback = _progress.reporter(progress)
    try:
        return _native.build(
            inputs if isinstance(inputs, (str, bytes, os.PathLike)) else iter(inputs),
            output,
            lossy=lossy,
            order=order,
            model=model,
            model_options=dict(model_options) if model_options is not None else None,
            max_order=max_order,
            periods=list(periods) if periods is not None else None,
            tile_depth=tile_depth,
            zstd_level=zstd_level,
            toggle_block=toggle_block,
            skip_bad=skip_bad,
            resolution=resolution,
            allow_mostly_skipped=allow_mostly_skipped,
            tags=dict(tags) if tags is not None else None,
            created=created,
            memory=memory,
            tmp_dir=tmp_dir,
            start=start,
            step=step,
            times_file=times_file,
            times_from_names=times_from_names,
            topic=topic,
            time_source=time_source,
            progress=callback,
        )
    finally:
        _progress.close(callback)


def evaluate(
    path: PathLike,
    against: Inputs,
    *,
    progress: Union[bool, ProgressCallback, None] = False,
    start: Any = None,
    step: Union[str, float, None] = None,
    times_file: Optional[PathLike] = None,
    times_from_names: bool = False,
) -> Dict[str, Any]:
    """Compares a FROctomap file with ground-truth maps (``froctomap eval --json``).

    ``against``: maps given as to :func:`build` (directories, globs, manifests, files), e.g.
    later snapshots. Maps inside the file's span measure its reconstruction, maps after it its
    prediction, each against the static-mean and last-seen baselines. Returns a dict with
    ``inside``/``outside`` (numbers of maps), ``reconstruction`` and ``prediction`` (lists of
    ``[method, rates]`` pairs; ``rates`` over all, non-empty and dynamic voxels, each
    ``{"wrong": n, "total": n, "brier": x, "log_loss": x}``: thresholded errors, Brier score
    and log loss with p clipped to ``[log_loss_epsilon, 1 - log_loss_epsilon]``),
    ``reconstruction_calibration`` and ``prediction_calibration`` (per method, bins of p over
    the dynamic voxels: ``lower``, ``upper``, ``voxels``, ``mean_p``, ``occupied_fraction``),
    ``log_loss_epsilon`` and ``unmodelled_voxels``: the fields of ``froctomap eval --json``.
    """
    callback = _progress.reporter(progress)
    try:
        return _native.evaluate(
            path,
            _paths(against),
            start=start,
            step=step,
            times_file=times_file,
            times_from_names=times_from_names,
            progress=callback,
        )
    finally:
        _progress.close(callback)
