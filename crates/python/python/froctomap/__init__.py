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
from ._native import FroctFile, Map, __version__, convert, formats, info, open, parse_time
from . import _native
from ._progress import ProgressCallback

__all__ = [
    "DEFAULT_TILE_BUDGET",
    "FroctError",
    "FroctFile",
    "Map",
    "ProgressCallback",
    "__version__",
    "append",
    "build",
    "compact",
    "convert",
    "evaluate",
    "export",
    "formats",
    "generate",
    "info",
    "map_from_message",
    "message_from_map",
    "open",
    "parse_time",
    "record",
    "render",
]


def __dir__() -> List[str]:
    # The public names only, not the typing helpers this module imports.
    return sorted(__all__)

PathLike = Union[str, "os.PathLike[str]"]

#: The default ``tile_budget`` of :func:`compact` and :func:`record` (bytes): the library's.
DEFAULT_TILE_BUDGET: int = _native._DEFAULT_TILE_BUDGET
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
    model: Optional[str] = None,
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
    components per voxel or ``"auto"`` (chosen per voxel, up to ``max_order``). ``model``
    (default ``None``: the command line's default, ``fremen-periods``),
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
            _maps(inputs),
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
    stride: int = 1,
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
    ``stride``: compare every ``stride``-th map in time order (``eval --stride``), for long
    held-out series; each map compared is checked against every cell of the file.
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
            stride=stride,
            progress=callback,
        )
    finally:
        _progress.close(callback)


def _model_options(model_options: Optional[Mapping[str, Any]]) -> Optional[Dict[str, Any]]:
    return dict(model_options) if model_options is not None else None


def _maps(inputs: Any) -> Any:
    """Inputs for the native calls: a path as it is, else an iterator whose ``(time,
    message)`` pairs carry map bytes (messages turned into their map files)."""
    if isinstance(inputs, (str, bytes, os.PathLike)):
        return inputs
    return (_map_item(item) for item in inputs)


def _map_item(item: Any) -> Any:
    if isinstance(item, tuple) and len(item) == 2 and not isinstance(item[1], (bytes, str, os.PathLike)):
        time, message = item
        if hasattr(message, "data") or isinstance(message, Mapping):
            return (time, map_from_message(message))
    return item


def append(
    file: PathLike,
    inputs: Union[Inputs, TimedMaps],
    *,
    model_options: Optional[Mapping[str, Any]] = None,
    skip_bad: bool = False,
    tags: Optional[Mapping[str, Any]] = None,
    appended: Any = None,
    format_version: Optional[str] = None,
    memory: Optional[int] = None,
    tmp_dir: Optional[PathLike] = None,
    start: Any = None,
    step: Union[str, float, None] = None,
    times_file: Optional[PathLike] = None,
    times_from_names: bool = False,
    progress: Union[bool, ProgressCallback, None] = True,
) -> Dict[str, Any]:
    """Adds later snapshots to a FROctomap file (``froctomap append --json``).

    ``inputs`` as for :func:`build` (paths, or ``(time, bytes)`` / ``(time, message)``
    pairs). A 1.x file is rewritten (every model refitted on the whole history: give the
    ``model_options`` of its build), atomically; a 2.0 file, or any file with
    ``format_version="2.0"``, gets the snapshots as one committed segment (a 1.x file is
    converted first). ``appended`` (a time) stores a fixed append time for reproducible
    files; ``tags`` replace the file's tags. Returns the report as a dict (``added``,
    ``samples``, ``file_bytes``, ``segments``, ...).
    """
    callback = _progress.reporter(progress)
    try:
        return _native.append(
            file, _maps(inputs), model_options=_model_options(model_options),
            skip_bad=skip_bad, tags=dict(tags) if tags is not None else None,
            appended=appended, format_version=format_version, memory=memory,
            tmp_dir=tmp_dir, start=start, step=step, times_file=times_file,
            times_from_names=times_from_names, progress=callback,
        )
    finally:
        _progress.close(callback)


def record(
    file: PathLike,
    sources: Any,
    *,
    commit_every: Union[int, str, float, None] = None,
    skip_bad: bool = False,
    model_options: Optional[Mapping[str, Any]] = None,
    auto_compact: Union[bool, str] = False,
    memory: Optional[int] = None,
    tmp_dir: Optional[PathLike] = None,
    tile_depth: Optional[int] = None,
    tile_budget: Optional[int] = DEFAULT_TILE_BUDGET,
) -> Dict[str, Any]:
    """Adds maps to a FROctomap 2.0 file as they come (``froctomap record``): one segment
    is committed (durably, under the file's writer lock) every ``commit_every`` maps (an
    int) or so much time (``"5s"``, ``"1min"``, seconds as a float; default 5 s), and at
    the end.

    ``sources``: a path (a directory, glob, manifest, map file, recording), or an iterable
    (a generator too, read as it yields) of paths, of ``(time, bytes)`` pairs (``.bt``/
    ``.ot`` file contents) or of ``(time, message)`` pairs (``octomap_msgs/Octomap``
    messages, e.g. from ``rosbags``: see :func:`map_from_message`). Maps not later than the
    last one taken (the file's last sample at first) are skipped and counted. A missing file
    gets the first commit's maps as its base (the default model, lossless); a 1.x file is
    converted to 2.0 first. A failure (or Ctrl-C) commits the maps taken before it, then
    raises. Returns a summary: ``committed_maps``, ``commits``, ``older``, ``bad``,
    ``compactions``, ``opened`` (``"living"``, ``"converted"``, ``"missing"``) and
    ``events`` (one dict per commit, compaction, map left out or commit retried as two
    halves after an error, its kind under ``"event"``).

    ``auto_compact``: ``False`` (the default: the caller decides when to ``compact``),
    ``True`` (in place after the commit that makes a compaction due, as ``froctomap
    record``) or ``"background"`` (on a thread of its own while maps keep being taken; the
    maps committed meanwhile are added to the result, which then replaces the file; the
    end waits for it, and Ctrl-C abandons it). ``tile_depth``: a new file's tiles
    (``record --tile-depth``; default 10; an existing file keeps its own): smaller tiles
    (12) keep the compactions of a long recording in less memory. ``tile_budget``: the
    compactions' (see :func:`compact`).
    """
    return _native.record(
        file, _maps(sources), commit_every=commit_every, skip_bad=skip_bad,
        model_options=_model_options(model_options), auto_compact=auto_compact,
        memory=memory, tmp_dir=tmp_dir, tile_depth=tile_depth, tile_budget=tile_budget,
    )


def compact(
    file: PathLike,
    output: Optional[PathLike] = None,
    *,
    format_version: str = "2.0",
    model_options: Optional[Mapping[str, Any]] = None,
    created: Any = None,
    memory: Optional[int] = None,
    tmp_dir: Optional[PathLike] = None,
    lossy: bool = False,
    tile_depth: Optional[int] = None,
    tile_budget: Optional[int] = DEFAULT_TILE_BUDGET,
    progress: Union[bool, ProgressCallback, None] = True,
) -> Dict[str, Any]:
    """Rewrites a FROctomap file's base and segments as one base (``froctomap compact
    --json``): in place (atomically, under the writer lock of a 2.0 file) or into
    ``output``. ``format_version``: ``"2.0"`` (a living map), ``"1.2"`` or ``"1.1"`` (for
    older readers). Every model is refitted on the whole history: give the
    ``model_options`` of the build. ``created`` fixes the creation time (reproducible
    files). ``lossy``: the models without the outlier set (``build --lossy``'s file), only
    into ``output``. ``tile_depth``: the result's tiles, the file's depth or deeper, smaller
    tiles that keep a long history's compactions in less memory (``compact --tile-depth``).
    Without it, ``tile_budget`` (bytes; ``None``: keep the file's depth) chooses: when the
    largest tile's history, as the last build or compaction measured it and grown with the
    maps since, passes it, the result's tiles go one level deeper (``compact
    --tile-budget``). Returns the report as a dict.
    """
    callback = _progress.reporter(progress)
    try:
        return _native.compact(
            file, output, format_version=format_version,
            model_options=_model_options(model_options), created=created, memory=memory,
            tmp_dir=tmp_dir, lossy=lossy, tile_depth=tile_depth, tile_budget=tile_budget,
            progress=callback,
        )
    finally:
        _progress.close(callback)


def export(
    file: PathLike,
    output: PathLike,
    *,
    start: Any,
    end: Any,
    every: Union[str, float],
    mode: str = "predict",
    format: Optional[str] = None,
    prefix: str = "map",
    overwrite: bool = False,
    profile: str = "ros2",
    frame_id: str = "map",
    topic_prefix: str = "",
    threshold: float = 0.5,
    progress: Union[bool, ProgressCallback, None] = True,
) -> Dict[str, Any]:
    """Writes maps of a FROctomap file at ``start``, ``start + every``, ... up to ``end``
    (``froctomap export --from START --to END --every EVERY``): into the directory
    ``output``, one ``.bt``/``.ot`` file per map (``format``) and a ``manifest.csv``; or,
    for ``format="mcap"`` or an output named ``*.mcap``, into one MCAP file; for
    ``format="rosbag"`` or ``*.bag``, into one ROS 1 bag; for ``format="ros2bag"`` (only
    so), into a new ROS 2 bag directory ``output`` (``metadata.yaml`` and
    ``NAME_0.mcap``; an existing one is refused). ``mode``:
    ``"predict"``, ``"retrieve"`` or ``"auto"`` (retrieved inside the file's span,
    predicted outside). An MCAP file takes ``profile`` (``"ros2"``: CDR messages only;
    ``"foxglove"``: also Foxglove's point cloud and cubes; bags take ``"ros2"`` only),
    ``frame_id``, ``topic_prefix``
    (``"/robot1"``: ``/robot1/octomap_binary``...) and ``threshold`` (predicted cells drawn
    where p > threshold), as ``export --profile/--frame-id/--topic-prefix/--threshold``
    (docs/ROS.md). Returns ``{"files": [[path, time], ...], "manifest", "bytes", ...}``.
    """
    callback = _progress.reporter(progress)
    try:
        return _native.export(
            file, output, start=start, end=end, every=every, mode=mode, format=format,
            prefix=prefix, overwrite=overwrite, profile=profile, frame_id=frame_id,
            topic_prefix=topic_prefix, threshold=threshold, progress=callback,
        )
    finally:
        _progress.close(callback)


def message_from_map(data: bytes) -> Dict[str, Any]:
    """The fields of the ``octomap_msgs/Octomap`` message holding the map file ``data``
    (a ``.bt`` or ``.ot`` file's bytes), as octomap_msgs' ``binaryMapToMsg``/``fullMapToMsg``
    fill them: ``binary`` (``True`` for a ``.bt``), ``id`` (``"OcTree"``), ``resolution``
    and ``data`` (the file's body behind its text header, a numpy int8 array as ``rosbags``
    and ``rclpy`` messages hold it). Add a ``header`` and build the message, e.g. with
    ``rosbags``: ``Octomap(header=Header(stamp=..., frame_id="map"), **fields)``.
    """
    import numpy

    fields = _native.octomap_message_fields(bytes(data))
    fields["data"] = numpy.frombuffer(fields["data"], dtype=numpy.int8).copy()
    return fields


def map_from_message(message: Any) -> bytes:
    """The map file an ``octomap_msgs/Octomap`` message holds (a ``.bt`` file's bytes for a
    binary message, else an ``.ot`` file's): its ``data`` behind the header OctoMap writes,
    as octomap_msgs' ``msgToMap`` reads it. ``message``: any object with the fields
    ``binary``, ``id``, ``resolution`` and ``data`` (a ``rosbags`` or ``rclpy`` message, an
    ``OctomapWithPose``'s ``octomap``) or a dict of them; ``data`` as bytes, a numpy array,
    an ``array.array`` or a list of ints.
    """
    if isinstance(message, Mapping):
        get = message.__getitem__
    else:
        get = lambda name: getattr(message, name)  # noqa: E731
    data = get("data")
    if hasattr(data, "tobytes"):
        data = data.tobytes()
    elif not isinstance(data, (bytes, bytearray)):
        data = bytes(int(b) & 0xFF for b in data)
    return _native.octomap_message_file(bool(get("binary")), str(get("id")), float(get("resolution")), bytes(data))


#: The font pictures use where neither ``$FROCTOMAP_FONT`` nor a system DejaVu Sans is
#: found: DejaVu Sans, shipped in the wheel (Bitstream Vera license, fonts/LICENSE-DejaVu.txt).
_FONT = os.path.join(os.path.dirname(__file__), "fonts", "DejaVuSans.ttf")


def render(
    file: PathLike,
    output: PathLike,
    *,
    t: Any = None,
    slice: Optional[str] = None,
    dynamics: bool = False,
    width: int = 1200,
) -> Dict[str, Any]:
    """Draws a FROctomap file into a PNG picture (``froctomap render``), the same bytes as
    the command line: the map at ``t`` seen from above (inside the file's span the snapshot
    observed then, outside it the prediction, p > 0.5), ``slice="z=0.5"`` for a horizontal
    cut, or ``dynamics=True`` for where the world changes. The text is set in DejaVu Sans
    (``$FROCTOMAP_FONT``, else the system's, else the copy the package ships). Returns
    ``{"output", "kind", "time", "width", "height"}``.
    """
    return _native.render(file, output, t=t, slice=slice, dynamics=dynamics, width=width,
                          font=_FONT if os.path.isfile(_FONT) else None)


#: The base map of ``generate`` by default, where Debian's liboctomap-dev installs it.
_DEFAULT_BASE = "/usr/share/doc/liboctomap-dev/examples/data/geb079.bt"


def generate(
    output: PathLike,
    *,
    base: Optional[PathLike] = None,
    days: float = 2.0,
    step: Union[str, float] = "10min",
    start: Any = None,
    seed: int = 1,
    real_doors: Optional[PathLike] = None,
    jitter: float = 0.0,
    missed: float = 0.0,
    noise: Optional[float] = None,
    partial: Optional[float] = None,
    spec: Optional[PathLike] = None,
    format: Optional[str] = None,
    progress: Union[bool, ProgressCallback, None] = True,
) -> Dict[str, Any]:
    """Writes a realistic, deterministic series of OctoMap snapshots made from a real map
    (``froctomap generate -o OUTPUT``): doors, people, chairs and objects change over
    ``days`` at every ``step`` from ``start`` (default 2016-01-04T00:00:00Z); the same
    ``seed`` gives the same bytes as the command line. ``base``: the real map; by default
    OctoMap's FR-079 corridor scan where Debian's liboctomap-dev installs it
    (``/usr/share/doc/liboctomap-dev/examples/data/geb079.bt``), which a pip install does not
    bring: without it, pass ``base=`` (FroctError says so). ``real_doors``: door recordings
    (``unix_time state`` lines) that drive some doors. Returns ``snapshots``, ``bytes``,
    ``start``, ``end`` and the ``manifest`` path.
    """
    if base is None and os.path.isfile(_DEFAULT_BASE):
        base = _DEFAULT_BASE
    callback = _progress.reporter(progress)
    try:
        return _native.generate(
            output, base=base, days=days, step=step, start=start, seed=seed,
            real_doors=real_doors, jitter=jitter, missed=missed, noise=noise, partial=partial,
            spec=spec, format=format, progress=callback,
        )
    finally:
        _progress.close(callback)
