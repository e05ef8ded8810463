"""Type stubs of the extension module ``froctomap._native`` (the Rust part of the package)."""

import os
import pathlib
from datetime import date, datetime
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
_DEFAULT_TILE_BUDGET: int

PathLike = Union[str, os.PathLike[str]]
#: Unix seconds, a datetime or date (naive: UTC), ISO 8601 text, numpy.datetime64, or
#: "index:N" / "index:-N" / "last" (a sample of the file's axis).
Time = Union[int, float, str, datetime, date, np.datetime64]

def open(path: PathLike) -> FroctFile:
    """Opens a FROctomap file; raises FroctError when it is missing, damaged or not one."""

def parse_time(t: Time) -> Union[float, Tuple[str, int]]:
    """Reads a time as the command line's --time: Unix seconds of an instant, or
    ("index", N) / ("from_end", N) for a sample query."""

def build(inputs: Any, output: PathLike, **options: Any) -> Dict[str, Any]:
    """See froctomap.build."""

def evaluate(path: PathLike, against: List[Any], **options: Any) -> Dict[str, Any]:
    """See froctomap.evaluate."""

def append(file: PathLike, inputs: Any, **options: Any) -> Dict[str, Any]:
    """See froctomap.append."""

def record(file: PathLike, sources: Any, **options: Any) -> Dict[str, Any]:
    """See froctomap.record."""

def compact(file: PathLike, output: Optional[PathLike] = None, **options: Any) -> Dict[str, Any]:
    """See froctomap.compact."""

def export(file: PathLike, output: PathLike, **options: Any) -> Dict[str, Any]:
    """See froctomap.export."""

def render(file: PathLike, output: PathLike, **options: Any) -> Dict[str, Any]:
    """See froctomap.render."""

def generate(output: PathLike, **options: Any) -> Dict[str, Any]:
    """See froctomap.generate."""

def convert(
    input: PathLike,
    output: PathLike,
    *,
    format: Optional[str] = None,
    input_format: Optional[str] = None,
) -> Dict[str, Any]:
    """Converts one map file into another format (``froctomap convert``): the output's
    extension names the format unless ``format`` does; the output is written atomically
    and is never the input. Returns ``input_format``, ``output_format``, ``leaves`` and the
    reader's ``warnings``."""

def formats() -> List[Dict[str, Any]]:
    """The registered formats, as ``froctomap formats --json`` lists them: a dict per format
    (``name``, ``kind``: ``"map"``, ``"series"`` or ``"recording"``, ``backend``: a map
    format's implementation, else None, ``extensions``, ``read``, ``write``,
    ``description``). The wheel reads and writes maps with the native codec only: the
    command line's ``octomap`` backend rows are not here."""

def info(path: PathLike, *, count: bool = False, input_format: Optional[str] = None) -> Dict[str, Any]:
    """Describes a file as ``froctomap info --json`` does: a FROctomap file (the fields of
    ``FroctFile.info``; ``count=True`` recounts its cells), one map file (format,
    resolution, nodes, leaves, voxels, bounds, warnings) or a recording (a ROS 1 bag, an
    MCAP file, a ROS 2 bag directory: ``format``, ``messages``, ``start``, ``end``,
    ``duration_s`` and ``topics``, each with ``topic``, ``type``, ``encoding``,
    ``messages`` and its first and last log times)."""

def octomap_message_fields(data: bytes) -> Dict[str, Any]:
    """The octomap_msgs/Octomap fields of a map file (see froctomap.message_from_map)."""

def octomap_message_file(binary: bool, id: str, resolution: float, data: bytes) -> bytes:
    """The map file of octomap_msgs/Octomap fields (see froctomap.map_from_message)."""

class FroctFile:
    """An open FROctomap file (from froctomap.open); a context manager."""

    @property
    def path(self) -> pathlib.Path:
        """The path given to open."""
    @property
    def times(self) -> npt.NDArray[np.float64]:
        """Unix seconds of every sample of the time axis, shape (samples,)."""
    @property
    def times_ns(self) -> npt.NDArray[np.int64]:
        """Nanoseconds since 1970 of every sample, shape (samples,)."""
    @property
    def observed(self) -> npt.NDArray[np.bool_]:
        """Whether each sample holds a snapshot, shape (samples,)."""
    @property
    def resolution(self) -> float:
        """Voxel edge length, metres."""
    @property
    def info(self) -> Dict[str, Any]:
        """The fields of `froctomap info --json`."""
    def describe(self, count: bool = False) -> Dict[str, Any]:
        """info; count=True recounts the cells from every tile."""
    def retrieve(self, t: Time, nearest: bool = False) -> Map:
        """The map as observed at t (the snapshot at or before it; nearest=True: the
        closest). Warns when t is after the last snapshot; raises FroctError before the
        first one or for an index beyond the axis."""
    def predict(self, t: Time) -> Map:
        """The map predicted for any instant t (p(t) per cell)."""
    def probability(
        self, t: Union[Time, List[Time], npt.ArrayLike], points: npt.ArrayLike
    ) -> npt.NDArray[np.float64]:
        """p(t) at each point of an (N, 3) array (metres), shape (N,); NaN where the file has
        no cell. Several instants (a list, tuple or array of T times): shape (T, N), in one
        call without the interpreter lock."""
    def history(
        self, point: npt.ArrayLike, start: Optional[Time] = None, end: Optional[Time] = None
    ) -> Dict[str, Any]:
        """The story of the voxel at point (x, y, z): its cell, class, model, and per sample
        the time, the observed state and the model's p."""
    def anomalies(
        self, snapshot: PathLike, t: Optional[Time] = None, expect: str = "model"
    ) -> Dict[str, Any]:
        """What is unusual in an OctoMap snapshot at time t (default: the time in its file
        name), as `froctomap anomalies --json` reports it: time, unix_time, scored_voxels,
        surprising_voxels, and regions (min, max, voxels, score, kind) most surprising
        first. expect: "model", "static-mean" or "last-seen"."""
    @property
    def version(self) -> str:
        """The format version, "major.minor" ("2.0" for a living map)."""
    @property
    def segments(self) -> int:
        """Committed segments after the base of a 2.0 file (0 for 1.x)."""
    def refresh(self) -> bool:
        """Sees what was committed to a 2.0 file since open (or the last refresh); True
        when there is something new. Maps taken before keep their view."""
    def close(self) -> None:
        """Closes the file; maps taken from it stay usable."""
    def __enter__(self) -> FroctFile: ...
    def __exit__(self, *args: Any) -> bool: ...
    def __len__(self) -> int:
        """Samples of the time axis."""

class Map:
    """A map from FroctFile.retrieve (as observed) or FroctFile.predict (p(t) per cell)."""

    @property
    def kind(self) -> str:
        """"observed" or "predicted"."""
    @property
    def time(self) -> float:
        """The map's time, Unix seconds."""
    @property
    def iso_time(self) -> str:
        """The map's time, ISO 8601 (UTC)."""
    @property
    def sample(self) -> Optional[int]:
        """The sample of a retrieved map; None for a predicted one."""
    @property
    def resolution(self) -> float:
        """Voxel edge length, metres."""
    def to_bt_bytes(self) -> bytes:
        """The .bt file's bytes, exactly what the command line writes."""
    def to_ot_bytes(self) -> bytes:
        """The .ot file's bytes, exactly what the command line writes."""
    def write(self, path: PathLike, format: Optional[str] = None) -> int:
        """Writes the map (format from the extension, or "bt"/"ot"); returns its leaves."""
    def point_cloud(
        self, max_points: int = 50_000_000
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(occupied, free) voxel centres, each of shape (N, 3), metres."""
    def leaves(self, with_p: bool = False) -> Tuple[npt.NDArray[Any], ...]:
        """(centres (N, 3), edge lengths (N,), occupied (N,)) of the map's leaves; with
        with_p=True also p (N,), each leaf's occupancy probability (clamped as OctoMap
        stores it)."""
    def search(
        self, points: npt.ArrayLike
    ) -> Tuple[npt.NDArray[np.int8], npt.NDArray[np.float64]]:
        """(state, p) at each point of an (N, 3) array, as octomap-python's search and
        isNodeOccupied/getOccupancy: state 1 occupied, 0 free, -1 unknown; p NaN where
        unknown."""
    def __len__(self) -> int:
        """Leaves of the map."""
