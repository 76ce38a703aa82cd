"""The batch manifest: which videos to fit, with which equation and settings.

Two formats, one meaning. A CSV is what a lab already keeps for a dataset (one row per
clip, edited in a spreadsheet, columns such as `true.gamma` filled in from the lab book).
A TOML file suits a hand-written batch: a `[defaults]` table shared by every job, typed
values, and equations with commas or quotes without CSV escaping. Both are read into the
same rows and validated by the same code, so every key below works in both.

CSV (`videos.csv`; empty cells mean "not set"; lines starting with # are comments):

    video,setting,eq,fps,true.gamma
    led/a.mp4,led,I' = -gamma*I,30,0.8
    led/b.mp4,led,I' = -gamma*I,30,0.8

TOML (`batch.toml`):

    [defaults]
    eq = "z'' + g1*z' + g0*z = 0"
    restarts = 3
    true = { g0 = 4.0016, g1 = 0.08 }

    [[job]]
    video = "motion/1.mp4"
    setting = "motion"

Keys (a row's value wins over `[defaults]`, which wins over the command line's flags):

    video          the video, relative to the manifest's folder (required)
    equation       equation text (contains '='), an equation file (*.toml) or a shipped system name
    eq | eq_file | system   the same, explicitly (give one of the four)
    setting        label of the per-setting aggregate (default "default")
    name           the job's folder name (default: row number and video stem, e.g. 003-clip)
    fps start end roi size color stride mask calibrate scale train_fraction   as in `fitode VIDEO`
    prior          "MEAN,STD"
    free           constant names to free, separated by spaces or commas
    observe        the observation model, as --observe ("position", "x=position;y=size")
    const.NAME     fix a constant;  init.NAME   start every restart there
    const  init    the same as --const/--init text, "L=1,z=0.1" (merged with const.NAME columns)
    true.NAME      the known true value, for the summary's relative error
    restarts max_steps seed window integrator ...   any trainer option (TrainConfig field)
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import re
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from fitode.errors import FitodeError

EQUATION_KEYS = ("equation", "eq", "eq_file", "system")
VIDEO_KEYS = ("fps", "start", "end", "roi", "size", "color", "stride", "mask", "calibrate", "scale", "train_fraction")
MODEL_KEYS = ("prior", "free", "observe", "const", "init")
META_KEYS = ("video", "setting", "name")
MAP_PREFIXES = ("const", "init", "true")
# files the batch writes beside the job folders
RESERVED_NAMES = {"batch.json", "summary.csv", "summary.json", "aggregate.csv", "aggregate.json",
                  "estimates.csv"}
# Options the batch sets itself, or that make no sense per job (each job has one core: no threads).
_NOT_PER_JOB = {"prior", "device", "threads"}
# The flags of `fitode VIDEO` (argparse dest names) that are no manifest column, and why. Every
# other flag is a column of the same name (tests/test_batch_columns.py holds the two together).
CLI_ONLY = {
    "help": "prints help; no job",
    "out": "the batch names each job's folder (the 'name' column) under its own --out",
    "quiet": "output only: a batch's workers print nothing of their own",
    "json": "output only: each job's result.json is in its folder",
    "no_plots": "output only: set once for the batch by `fitode batch --no-plots`",
    "device": "set once for the batch by `fitode batch --device`, not per job",
    "threads": "set by the batch: each worker gets its share of the cores",
}


class ManifestError(FitodeError):
    """A malformed manifest: the message names the file, the row and the column."""


@dataclass(frozen=True)
class Job:
    """One video to fit: everything a worker needs, and nothing that lives only in the driver.

    index: 1-based position among the manifest's jobs. name: the job's folder under the batch's
    out dir. kwargs: the keyword arguments of `fitode.pipeline.run_job` (besides video and
    out_dir). fingerprint: what the settings hash covers (the kwargs, the video's path relative to
    the manifest, its size and mtime, an equation file's text). truth: known true constants.
    """

    index: int
    name: str
    video: Path
    setting: str
    where: str
    kwargs: dict[str, Any]
    truth: dict[str, float] = field(default_factory=dict)
    fingerprint: dict[str, Any] = field(default_factory=dict)

    @property
    def settings_hash(self) -> str:
        blob = json.dumps(self.fingerprint, sort_keys=True, separators=(",", ":"), default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


@dataclass
class Manifest:
    path: Path
    jobs: list[Job]

    @property
    def settings(self) -> list[str]:
        return list(dict.fromkeys(j.setting for j in self.jobs))


def train_option_types() -> dict[str, type]:
    """Trainer options a row may set, with the type its value converts to."""
    from fitode.train.config import TrainConfig

    hints = typing.get_type_hints(TrainConfig)
    out: dict[str, type] = {}
    for f in dataclasses.fields(TrainConfig):
        if f.name in _NOT_PER_JOB:
            continue
        hint = hints[f.name]
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        base = args[0] if args else hint
        if base in (int, float, bool, str):
            out[f.name] = base
    return out


def load_manifest(path: str | Path, defaults: Mapping[str, Any] | None = None, *,
                  check_equations: bool = True) -> Manifest:
    """Read and validate a CSV or TOML manifest.

    defaults: values for keys a row (and the TOML `[defaults]`) leaves unset, e.g. the command
    line's --restarts. check_equations: parse each distinct equation now, so that a typo in the
    last row fails before the first job runs.
    """
    path = Path(path)
    if not path.is_file():
        raise ManifestError(f"no such manifest: {path}")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        raw_rows, file_defaults = _read_csv(path), {}
    elif suffix == ".toml":
        raw_rows, file_defaults = _read_toml(path)
    else:
        raise ManifestError(f"{path.name}: a manifest is a .csv or a .toml file")
    if not raw_rows:
        raise ManifestError(f"{path.name}: no jobs")
    options = train_option_types()
    base = path.parent.resolve()
    cli = _Row(dict(defaults or {}), "the command line", options, Path.cwd(), path.name)
    fdef = _Row(file_defaults, "[defaults]", options, base, path.name)
    cli.check_keys(is_row=False)
    fdef.check_keys(is_row=False)
    jobs = []
    for i, (where, raw) in enumerate(raw_rows, start=1):
        row = _Row(raw, where, options, base, path.name)
        row.check_keys()
        jobs.append(_make_job(i, len(raw_rows), row, fdef, cli))
    _check_unique_names(jobs, path.name)
    if check_equations:
        _check_equations(jobs, path.name)
    return Manifest(path.resolve(), jobs)


# --- reading ------------------------------------------------------------------------------

def _read_csv(path: Path) -> list[tuple[str, dict[str, Any]]]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{path.name}: not UTF-8 text ({exc.reason})") from None
    rows: list[tuple[str, dict[str, Any]]] = []
    header: list[str] | None = None
    reader = csv.reader(text.splitlines())
    try:
        for cells in reader:
            line = reader.line_num
            if not cells or all(not c.strip() for c in cells) or cells[0].lstrip().startswith("#"):
                continue
            cells = [c.strip() for c in cells]
            if header is None:
                header = cells
                for col, name in enumerate(header, start=1):
                    if not name:
                        raise ManifestError(f"{path.name} line {line}: column {col} of the header has no name")
                    if header.count(name) > 1:
                        raise ManifestError(f"{path.name} line {line}: column '{name}' appears twice")
                if "video" not in header:
                    raise ManifestError(f"{path.name} line {line}: the header has no 'video' column")
                continue
            if len(cells) > len(header):
                extra = [c for c in cells[len(header):] if c]
                if extra:
                    raise ManifestError(f"{path.name} line {line}: {len(cells)} cells but the header has "
                                        f"{len(header)} columns (quote values that contain commas)")
            row = {k: v for k, v in zip(header, cells) if v != ""}
            rows.append((f"line {line}", row))
    except csv.Error as exc:
        raise ManifestError(f"{path.name} line {reader.line_num}: {exc}") from None
    return rows


def _read_toml(path: Path) -> tuple[list[tuple[str, dict[str, Any]]], dict[str, Any]]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path.name}: {exc}") from None
    unknown = set(data) - {"defaults", "job"}
    if unknown:
        raise ManifestError(f"{path.name}: unknown table '{sorted(unknown)[0]}' (expected [defaults] and [[job]])")
    defaults = data.get("defaults", {})
    jobs = data.get("job", [])
    if not isinstance(defaults, dict):
        raise ManifestError(f"{path.name}: 'defaults' must be a table")
    if not isinstance(jobs, list) or not all(isinstance(j, dict) for j in jobs):
        raise ManifestError(f"{path.name}: jobs are written as [[job]] tables")
    return [(f"job {i}", _flatten(j)) for i, j in enumerate(jobs, start=1)], _flatten(defaults)


def _flatten(table: dict[str, Any]) -> dict[str, Any]:
    """TOML's `true = {g = 1}` and `true.g = 1` -> {"true.g": 1}, as CSV columns spell it."""
    out: dict[str, Any] = {}
    for k, v in table.items():
        if k in MAP_PREFIXES and isinstance(v, dict):
            for kk, vv in v.items():
                out[f"{k}.{kk}"] = vv
        else:
            out[k] = v
    return out


# --- validation ---------------------------------------------------------------------------

class _Row:
    """One source of values (a row, the TOML defaults or the command line) and its place for messages."""

    def __init__(self, values: dict[str, Any], where: str, options: dict[str, type], base: Path, file: str):
        self.values, self.where, self.options, self.base, self.file = values, where, options, base, file

    def error(self, key: str, problem: str) -> ManifestError:
        where = self.where if self.where == "the command line" else f"{self.file} {self.where}"
        return ManifestError(f"{where}, column '{key}': {problem}")

    def check_keys(self, is_row: bool = True) -> None:
        known = set(EQUATION_KEYS + VIDEO_KEYS + MODEL_KEYS + META_KEYS) | set(self.options)
        for key, value in self.values.items():
            if not is_row and key in ("video", "name"):
                raise self.error(key, "belongs in a job's row, not in the defaults")
            if "." in key:
                prefix, _, name = key.partition(".")
                if prefix not in MAP_PREFIXES:
                    raise self.error(key, f"unknown column (dotted columns start with {', '.join(MAP_PREFIXES)})")
                if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
                    raise self.error(key, f"'{name}' is not a constant's name")
            elif key == "true":
                raise self.error(key, f"write one column per constant, e.g. '{key}.gamma'")
            elif key not in known:
                close = [k for k in sorted(known) if _close(k, key)]
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise self.error(key, f"unknown column{hint}")
            if isinstance(value, (dict, list)) and key not in ("roi", "size", "prior", "free", "observe"):
                raise self.error(key, f"expected a single value, got {type(value).__name__}")


def _close(a: str, b: str) -> bool:
    a, b = a.lower().replace("-", "_"), b.lower().replace("-", "_")
    if a == b:
        return True
    if abs(len(a) - len(b)) > 1:
        return False
    diff = sum(x != y for x, y in zip(a, b))
    return diff + abs(len(a) - len(b)) <= 1


def _make_job(index: int, count: int, row: _Row, fdef: _Row, cli: _Row) -> Job:
    sources = (row, fdef, cli)

    def pick(key: str) -> tuple[Any, _Row] | None:
        for src in sources:
            if key in src.values:
                return src.values[key], src
        return None

    def pick_map(prefix: str) -> dict[str, tuple[Any, _Row, str]]:
        out: dict[str, tuple[Any, _Row, str]] = {}
        for src in reversed(sources):  # later sources override earlier ones
            for k, v in src.values.items():
                if k.startswith(prefix + "."):
                    out[k.partition(".")[2]] = (v, src, k)
        return out

    if "video" not in row.values:
        raise row.error("video", "missing: every row names a video")
    video_rel = _text(row.values["video"], row, "video")
    video = (row.base / video_rel).resolve() if not Path(video_rel).is_absolute() else Path(video_rel)
    if not video.exists():
        raise row.error("video", f"no such file: {video_rel}")
    fingerprint: dict[str, Any] = {"video": _file_print(video, row.base)}
    kwargs: dict[str, Any] = {}

    # the equation: exactly one of the four keys, taken from the first source that has any
    eq_src = next((s for s in sources if any(k in s.values for k in EQUATION_KEYS)), None)
    if eq_src is None:
        raise row.error("equation", "missing: give 'equation' (or eq, eq_file, system) in the row, "
                                    "the defaults or on the command line")
    given = [k for k in EQUATION_KEYS if k in eq_src.values]
    if len(given) > 1:
        raise eq_src.error(given[1], f"give the equation once ('{given[0]}' is set too)")
    key = given[0]
    value = _text(eq_src.values[key], eq_src, key)
    if key == "equation":
        key = "eq" if "=" in value else ("eq_file" if value.lower().endswith(".toml") or "/" in value else "system")
    if key == "eq_file":
        eq_path = (eq_src.base / value).resolve()
        if not eq_path.is_file():
            raise eq_src.error(given[0], f"no such equation file: {value}")
        kwargs["eq_file"] = str(eq_path)
        fingerprint["eq_file_text"] = eq_path.read_text(encoding="utf-8", errors="replace")
    else:
        kwargs[key] = value

    for key in VIDEO_KEYS:
        got = pick(key)
        if got is not None:
            kwargs[key] = _convert_video(key, got[0], got[1])
    if (got := pick("mask")) is not None:
        mask = (got[1].base / kwargs["mask"]).resolve()
        if not mask.exists():
            raise got[1].error("mask", f"no such file: {kwargs['mask']}")
        kwargs["mask"] = str(mask)
        fingerprint["mask"] = _file_print(mask, got[1].base)
    if "start" in kwargs and "end" in kwargs and kwargs["end"] <= kwargs["start"]:
        raise row.error("end", f"end {kwargs['end']:g} s is not after start {kwargs['start']:g} s")
    if (got := pick("prior")) is not None:
        kwargs["prior"] = _pair(got[0], got[1], "prior")
        if not kwargs["prior"][1] > 0:
            raise got[1].error("prior", "the standard deviation must be positive")
    if (got := pick("free")) is not None:
        kwargs["free"] = tuple(_names(got[0], got[1], "free"))
    if (got := pick("observe")) is not None:
        kwargs["observe"] = _observe(got[0], got[1])
    for prefix in ("const", "init"):
        values = {}
        if (got := pick(prefix)) is not None:  # "L=1,z=0.1" as after --const; dotted columns win
            values = _assignments(got[0], got[1], prefix)
        values.update({n: _float(v, src, k) for n, (v, src, k) in pick_map(prefix).items()})
        if values:
            kwargs[prefix] = dict(sorted(values.items()))
    for opt, typ in row.options.items():
        got = pick(opt)
        if got is not None:
            kwargs[opt] = _typed(got[0], typ, got[1], opt)

    truth = {n: _float(v, src, k) for n, (v, src, k) in pick_map("true").items()}
    got = pick("setting")
    setting = _text(got[0], got[1], "setting") if got else "default"
    if "name" in row.values:
        name = _text(row.values["name"], row, "name")
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", name):
            raise row.error("name", f"'{name}' is not a folder name (letters, digits, . _ -)")
        if name.lower() in RESERVED_NAMES:
            raise row.error("name", f"'{name}' is the name of one of the batch's own files")
    else:
        width = max(3, len(str(count)))
        stem = re.sub(r"[^A-Za-z0-9._-]+", "_", video.stem).strip("._") or "video"
        name = f"{index:0{width}d}-{stem}"
    fingerprint["kwargs"] = {k: v for k, v in kwargs.items() if k not in ("eq_file", "mask")}
    return Job(index=index, name=name, video=video, setting=setting, where=f"{row.file} {row.where}",
               kwargs=kwargs, truth=truth, fingerprint=fingerprint)


def _file_print(path: Path, base: Path) -> dict[str, Any]:
    """Where a file is (relative to the manifest, so moving the whole folder keeps it) and which version."""
    try:
        rel = path.relative_to(base).as_posix()
    except ValueError:
        rel = str(path)
    st = path.stat()
    return {"path": rel, "size": st.st_size, "mtime_ns": st.st_mtime_ns}


def _check_unique_names(jobs: list[Job], file: str) -> None:
    seen: dict[str, Job] = {}
    for job in jobs:
        if job.name in seen:
            raise ManifestError(f"{job.where}, column 'name': '{job.name}' is also the name of "
                                f"{seen[job.name].where.split(' ', 1)[1]}")
        seen[job.name] = job


def _check_equations(jobs: list[Job], file: str) -> None:
    """Parse each distinct equation once; unknown const./init./true. names are errors too."""
    try:
        from fitode.eqfile import resolve
    except ImportError:  # the equation layer is not there (a stripped install): workers will say
        return
    cache: dict[str, Any] = {}
    for job in jobs:
        k = job.kwargs
        key = json.dumps([k.get("eq"), k.get("eq_file"), k.get("system"), k.get("const"), k.get("free")],
                         sort_keys=True)
        if key not in cache:
            try:
                ode, _ = resolve(eq=k.get("eq"), eq_file=k.get("eq_file"), system=k.get("system"),
                                 const=k.get("const"), free=k.get("free", ()))
            except FitodeError as exc:
                col = next(c for c in ("eq", "eq_file", "system") if c in k)
                cache[key] = ManifestError(f"{job.where}, column '{col}': {exc}")
            else:
                cache[key] = ode
        ode = cache[key]
        if isinstance(ode, ManifestError):
            raise ode
        learnable = tuple(ode.learnable)
        if k.get("calibrate") is not None:
            from fitode.calibrate import parse_calibration  # --calibrate's own check, on the equation's states
            try:
                parse_calibration(k["calibrate"], ode.states)
            except FitodeError as exc:
                raise ManifestError(f"{job.where}, column 'calibrate': {exc}") from None
        if k.get("scale") is not None:
            from fitode.scale import parse_scale  # --scale's own check
            try:
                parse_scale(k["scale"])
            except FitodeError as exc:
                raise ManifestError(f"{job.where}, column 'scale': {exc}") from None
        if isinstance(k.get("observe"), dict):
            from fitode.train.observe.catalog import check_states
            try:
                check_states(k["observe"], ode.states)
            except FitodeError as exc:
                raise ManifestError(f"{job.where}, column 'observe': {exc}") from None
        for prefix, names in (("init", k.get("init", {})), ("true", job.truth)):
            for n in names:
                if n not in learnable:
                    raise ManifestError(f"{job.where}, column '{prefix}.{n}': '{n}' is not a learnable constant "
                                        f"of the equation (learnable: {', '.join(learnable) or 'none'})")


# --- value conversion ---------------------------------------------------------------------

def _text(value: Any, src: _Row, key: str) -> str:
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise src.error(key, f"expected text, got {value!r}")
    text = str(value).strip()
    if not text:
        raise src.error(key, "empty")
    return text


def _float(value: Any, src: _Row, key: str) -> float:
    if isinstance(value, bool):
        raise src.error(key, f"expected a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise src.error(key, f"expected a number, got {value!r}") from None
    if not math.isfinite(x):
        raise src.error(key, f"expected a finite number, got {value!r}")
    return x


def _int(value: Any, src: _Row, key: str) -> int:
    if isinstance(value, bool):
        raise src.error(key, f"expected a whole number, got {value!r}")
    if isinstance(value, int):
        return value
    try:
        x = float(str(value).strip())
    except ValueError:
        raise src.error(key, f"expected a whole number, got {value!r}") from None
    if not x.is_integer():
        raise src.error(key, f"expected a whole number, got {value!r}")
    return int(x)


def _bool(value: Any, src: _Row, key: str) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("true", "yes", "1", "y"):
        return True
    if text in ("false", "no", "0", "n"):
        return False
    raise src.error(key, f"expected true or false, got {value!r}")


def _typed(value: Any, typ: type, src: _Row, key: str) -> Any:
    x = _converted(value, typ, src, key)
    from fitode.errors import ConfigError
    from fitode.train.config import TrainConfig
    try:  # the option's own rule, as the flag's (fitode.options): `integrator = rk5` fails here, not in a worker
        TrainConfig(**{key: x})
    except ConfigError as exc:
        message = str(exc)
        raise src.error(key, message[len(key) + 1:] if message.startswith(key + " ") else message) from None
    return x


def _converted(value: Any, typ: type, src: _Row, key: str) -> Any:
    if typ is bool:
        return _bool(value, src, key)
    if typ is int:
        x = _int(value, src, key)
        if key in ("restarts", "max_steps", "window", "substeps", "patience", "batch_windows", "check_every") and x < 1:
            raise src.error(key, f"must be at least 1, got {x}")
        if key in ("min_steps", "seed") and x < 0:
            raise src.error(key, f"must not be negative, got {x}")
        return x
    if typ is float:
        return _float(value, src, key)
    return _text(value, src, key)


def _numbers(value: Any, src: _Row, key: str) -> list[Any]:
    if isinstance(value, list):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [value]
    return [p for p in re.split(r"[,\s]+", str(value).strip()) if p]


def _pair(value: Any, src: _Row, key: str) -> tuple[float, float]:
    if isinstance(value, dict):
        if set(value) != {"mean", "std"}:
            raise src.error(key, "expected {mean = M, std = S}")
        value = [value["mean"], value["std"]]
    parts = _numbers(value, src, key)
    if len(parts) != 2:
        raise src.error(key, f"expected MEAN,STD, got {value!r}")
    return _float(parts[0], src, key), _float(parts[1], src, key)


def _observe(value: Any, src: _Row) -> str | dict[str, str]:
    from fitode.train.observe.catalog import parse_observe  # --observe's own check
    try:
        return parse_observe(value if isinstance(value, dict) else _text(value, src, "observe"))
    except FitodeError as exc:
        raise src.error("observe", str(exc)) from None


def _assignments(value: Any, src: _Row, key: str) -> dict[str, float]:
    from fitode.names import parse_assignments  # --const/--init's own check
    try:
        return parse_assignments(_text(value, src, key), flag=key)
    except FitodeError as exc:
        raise src.error(key, str(exc)) from None


def _names(value: Any, src: _Row, key: str) -> list[str]:
    parts = value if isinstance(value, list) else re.split(r"[,\s]+", str(value).strip())
    names = [str(p).strip() for p in parts if str(p).strip()]
    for n in names:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n):
            raise src.error(key, f"'{n}' is not a constant's name")
    return names


def _convert_video(key: str, value: Any, src: _Row) -> Any:
    if key == "fps":
        x = _float(value, src, key)
        if x <= 0:
            raise src.error(key, f"must be positive, got {value!r}")
        return x
    if key in ("start", "end"):
        x = _float(value, src, key)
        if x < 0:
            raise src.error(key, f"seconds from the start of the video, got {value!r}")
        return x
    if key == "train_fraction":
        x = _float(value, src, key)
        if not 0 < x <= 1:
            raise src.error(key, f"must be in (0, 1], got {value!r}")
        return x
    if key == "roi":
        parts = _numbers(value, src, key)
        if len(parts) != 4:
            raise src.error(key, f"expected x,y,w,h, got {value!r}")
        x, y, w, h = (_int(p, src, key) for p in parts)
        if x < 0 or y < 0 or w < 1 or h < 1:
            raise src.error(key, f"expected x,y >= 0 and w,h >= 1, got {value!r}")
        return (x, y, w, h)
    if key == "size":  # WxH as typed after `fitode VIDEO --size` (a TOML list: [W, H]) -> (H, W)
        from fitode.video import VideoError, parse_size
        text = "x".join(str(_int(p, src, key)) for p in value) if isinstance(value, list) else str(value)
        try:
            return parse_size(text)
        except VideoError:
            raise src.error(key, f"expected WxH (width x height) in pixels such as 64x48, got {value!r}") from None
    if key == "color":
        return _bool(value, src, key)
    if key == "stride":
        if str(value).strip().lower() == "auto":
            return "auto"
        x = _int(value, src, key)
        if x < 1:
            raise src.error(key, f"expected 'auto' or a whole number >= 1, got {value!r}")
        return x
    return _text(value, src, key)  # mask, calibrate, scale
