"""POV-Ray's options: command-line switches (``+W640 +H480 +Iscene.pov +Oout.png +A0.3``) and INI
files (``Width=640``, one option a line, ``;`` comments, ``[sections]``), read in the order given,
the last setting of an option winning (``Library_Path`` adds up), as POV-Ray reads them.

:func:`read_options` folds command-line words into one :class:`PovOptions`. Options that do not
change the image here (the preview window, tile order, bounding, threads) are accepted silently;
options that would change it and are not rendered (a partial image, field rendering, jitter,
quality levels below full) and unknown ones are collected by name in ``PovOptions.ignored``, for one
warning line. A bad value is a :class:`SceneError` at ``file:line:col`` (an INI file) or naming the
switch (the command line).
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from ..errors import SceneError, SourceLoc

_TRUE = ("on", "true", "yes", "1")
_FALSE = ("off", "false", "no", "0")

# output file types: POV-Ray's letter → the file suffix written (Pillow writes those but PNG and EXR)
OUTPUT_TYPES = {"N": ".png", "S": ".png", "E": ".exr", "T": ".tga", "C": ".tga", "P": ".ppm",
                "J": ".jpg", "B": ".bmp"}
_TYPE_NAMES = {"H": "Radiance HDR"}


@dataclasses.dataclass
class PovOptions:
    """What POV-Ray's options ask for; None where an option was not given."""

    input: str | None = None
    output: str | None = None
    width: int | None = None
    height: int | None = None
    output_type: str | None = None  # a key of OUTPUT_TYPES
    bits: int | None = None  # per colour channel of a PNG
    antialias: bool | None = None
    threshold: float | None = None
    depth: int | None = None
    aa_gamma: float | None = None
    library_paths: list[str] = dataclasses.field(default_factory=list)
    initial_frame: int | None = None
    final_frame: int | None = None
    initial_clock: float | None = None
    final_clock: float | None = None
    cyclic: bool | None = None
    subset_start: int | None = None
    subset_end: int | None = None
    clock: float | None = None
    ignored: list[str] = dataclasses.field(default_factory=list)  # option names, in order, once each
    # the folder of the INI file that named ``input`` (a relative name is looked for there too)
    input_base: str | None = None

    def ignore(self, name: str) -> None:
        if name not in self.ignored:
            self.ignored.append(name)

    @property
    def animated(self) -> bool:
        return any(x is not None for x in (self.initial_frame, self.final_frame, self.initial_clock,
                                           self.final_clock, self.cyclic))


class _Bad(ValueError):
    """A value that does not fit its option (the message names what was expected)."""


def _bool(text: str) -> bool:
    t = text.strip().lower()
    if t in _TRUE:
        return True
    if t in _FALSE:
        return False
    raise _Bad(f"expected on or off, found {text!r}")


def _int(text: str, least: int | None = None) -> int:
    expected = f"expected a whole number{'' if least is None else f' ≥ {least}'}, found {text!r}"
    try:
        x = float(text)
    except ValueError:
        raise _Bad(expected) from None
    if not math.isfinite(x) or x != int(x) or (least is not None and x < least):
        raise _Bad(expected)
    return int(x)


def _float(text: str, least: float | None = None) -> float:
    try:
        x = float(text)
    except ValueError:
        raise _Bad(f"expected a number, found {text!r}") from None
    if not math.isfinite(x) or (least is not None and x < least):
        raise _Bad(f"expected a number{'' if least is None else f' ≥ {least:g}'}, found {text!r}")
    return x


def _file_type(text: str, opts: PovOptions) -> None:
    """``N``, ``N16``, ``E`` …: the type letter and, for PNG, the bits per channel."""
    m = re.fullmatch(r"([A-Za-z])(\d*)", text.strip())
    if m is None:
        raise _Bad(f"expected an output type letter (N, E, T, C, P, J, B), found {text!r}")
    letter = m.group(1).upper()
    if letter not in OUTPUT_TYPES:
        name = _TYPE_NAMES.get(letter)
        raise _Bad(f"output type {letter}{f' ({name})' if name else ''} is not written here: "
                   "use N (PNG), E (OpenEXR), T or C (TGA), P (PPM), J (JPEG) or B (BMP)")
    opts.output_type = letter
    if m.group(2):
        opts.bits = _int(m.group(2), least=1)


def _set(field, convert):
    def apply(text: str, opts: PovOptions) -> None:
        setattr(opts, field, convert(text))
    return apply


def _antialias_threshold(text: str, opts: PovOptions) -> None:
    opts.threshold = _float(text, least=0.0)


def _library(text: str, opts: PovOptions) -> None:
    opts.library_paths.append(text)


def _no_effect(text: str, opts: PovOptions) -> None:
    """An option about the preview, the console, the tile order, bounding or threads: it does not
    change the image written."""


def _unless(default: bool, name: str):
    """A switch accepted silently at ``default`` (what this program does), ignored by name else."""
    def apply(text: str, opts: PovOptions) -> None:
        if _bool(text) != default:
            opts.ignore(name)
    return apply


def _quality(text: str, opts: PovOptions) -> None:
    if _int(text) < 9:  # 9, 10, 11: everything we render (radiosity is not)
        opts.ignore("Quality")


def _sampling(text: str, opts: PovOptions) -> None:
    if _int(text) != 1:
        opts.ignore("Sampling_Method")  # method 2 (recursive adaptive) is rendered as method 1


# INI keys (lower case) → how a value applies
_KEYS = {
    "input_file_name": _set("input", str), "output_file_name": _set("output", str),
    "width": _set("width", lambda t: _int(t, least=1)), "height": _set("height", lambda t: _int(t, least=1)),
    "output_file_type": _file_type, "bits_per_color": _set("bits", lambda t: _int(t, least=1)),
    "antialias": _set("antialias", _bool), "antialias_threshold": _antialias_threshold,
    "antialias_depth": _set("depth", lambda t: _int(t, least=1)),
    "antialias_gamma": _set("aa_gamma", lambda t: _float(t, least=1e-6)),
    "library_path": _library,
    "initial_frame": _set("initial_frame", _int), "final_frame": _set("final_frame", _int),
    "initial_clock": _set("initial_clock", _float), "final_clock": _set("final_clock", _float),
    "cyclic_animation": _set("cyclic", _bool), "clock": _set("clock", _float),
    "subset_start_frame": _set("subset_start", _int), "subset_end_frame": _set("subset_end", _int),
    "output_to_file": _unless(True, "Output_to_File"),
    "display": _unless(False, "Display"), "continue_trace": _unless(False, "Continue_Trace"),
    "sampling_method": _sampling, "quality": _quality,
    "jitter": _unless(False, "Jitter"), "output_alpha": _unless(False, "Output_Alpha"),
    "field_render": _unless(False, "Field_Render"),
    # the preview, the console and its streams, aborts, tile order, bounding, threads, buffers
    **dict.fromkeys(
        ("pause_when_done", "verbose", "test_abort", "test_abort_count", "preview_start_size",
         "preview_end_size", "draw_vistas", "palette", "display_gamma", "warning_level",
         "render_block_size", "render_block_step", "render_pattern", "work_threads", "bounding",
         "bounding_method", "bounding_threshold", "split_unions", "remove_bounds", "light_buffer",
         "vista_buffer", "max_image_buffer_memory", "jitter_amount", "antialias_confidence",
         "debug_console", "fatal_console", "render_console", "statistic_console", "warning_console",
         "all_console", "odd_field"), _no_effect),
}

# command-line switches → their INI keys (a key without a handler above is ignored by name)
_SWITCHES = sorted({
    "KFI": "initial_frame", "KFF": "final_frame", "KI": "initial_clock", "KF": "final_clock",
    "KC": "cyclic_animation", "K": "clock", "SF": "subset_start_frame", "EF": "subset_end_frame",
    "A": "antialias", "AM": "sampling_method", "AG": "antialias_gamma", "R": "antialias_depth",
    "J": "jitter", "W": "width", "H": "height", "I": "input_file_name", "O": "output_file_name",
    "L": "library_path", "F": "output_file_type", "Q": "quality", "UA": "output_alpha",
    "UF": "field_render", "UO": "odd_field", "D": "display", "P": "pause_when_done", "V": "verbose",
    "X": "test_abort", "WT": "work_threads", "WL": "warning_level", "SP": "preview_start_size",
    "EP": "preview_end_size", "UD": "draw_vistas", "MB": "bounding", "BM": "bounding_method",
    "SU": "split_unions", "UR": "remove_bounds", "UL": "light_buffer", "UV": "vista_buffer",
    "MI": "max_image_buffer_memory", "GA": "all_console", "GD": "debug_console",
    "GF": "fatal_console", "GR": "render_console", "GS": "statistic_console", "GW": "warning_console",
    "SR": "start_row", "ER": "end_row", "SC": "start_column", "EC": "end_column",
    "C": "continue_trace", "HI": "include_header", "MV": "version", "GI": "create_ini",
}.items(), key=lambda item: -len(item[0]))
# switches that are on with + and off with -; some take a value after them as well
_FLAGS = {"antialias", "cyclic_animation", "jitter", "output_alpha", "field_render", "odd_field",
          "display", "pause_when_done", "verbose", "test_abort", "draw_vistas", "bounding",
          "split_unions", "remove_bounds", "light_buffer", "vista_buffer", "all_console",
          "debug_console", "fatal_console", "render_console", "statistic_console", "warning_console",
          "continue_trace"}
_FLAG_VALUES = {"display": "palette", "jitter": "jitter_amount", "test_abort": "test_abort_count",
                "bounding": "bounding_threshold"}


def _canonical(key: str) -> str:
    """``Pause_when_Done`` → ``Pause_When_Done`` (for messages)."""
    return "_".join(w[:1].upper() + w[1:].lower() for w in key.split("_"))


def apply_key(key: str, value: str, opts: PovOptions) -> None:
    """One ``Key=Value`` (raises ``_Bad``)."""
    k = key.strip().lower()
    value = value.strip()
    if len(value) >= 2 and value[0] == value[-1] == '"':
        value = value[1:-1]
    if not value:  # ``Final_Frame=`` (a template's blank, portfolio/__empty.ini): not given
        return
    handler = _KEYS.get(k)
    if handler is None:
        opts.ignore(_canonical(key.strip()))
        return
    handler(value, opts)


def apply_switch(word: str, opts: PovOptions) -> None:
    """One command-line switch, ``+W640`` or ``-D`` (raises ``_Bad``)."""
    sign, body = word[0], word[1:]
    for prefix, key in _SWITCHES:
        if not body.upper().startswith(prefix):
            continue
        rest, on = body[len(prefix):], "on" if sign == "+" else "off"
        if key == "antialias" and rest:  # +A0.3: on, with a threshold
            opts.antialias = sign == "+"
            _antialias_threshold(rest, opts)
        elif key == "output_file_type" and not rest:  # -F: no file
            apply_key("output_to_file", on, opts)
        elif key in _FLAGS:
            if rest and key not in _FLAG_VALUES:
                raise _Bad(f"expected nothing after {sign}{prefix}, found {rest!r}")
            apply_key(key, on, opts)
            if rest:
                apply_key(_FLAG_VALUES[key], rest, opts)
        elif not rest:
            raise _Bad(f"expected a value after {sign}{prefix}")
        else:
            apply_key(key, rest, opts)
        return
    opts.ignore(word)


def _is_text(data: bytes) -> bool:
    return b"\0" not in data[:65536]


def read_ini(path: str | Path, opts: PovOptions, section: str | None = None, _depth: int = 0) -> None:
    """The options of an INI file (or of its ``[section]``) into ``opts``. Without a section, the
    lines before the file's first section label; an INI file named on a line of its own (or by
    ``Include_Ini``) is read there."""
    path = Path(path)
    if _depth > 16:
        raise SceneError(f"INI files include each other more than 16 deep (at {path})")
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SceneError(f"cannot read INI file {str(path)!r}: {e.strerror or e}") from None
    if not _is_text(data):
        raise SceneError("not an INI file (binary data)", SourceLoc(str(path), 1, 1))
    text = data.decode("utf-8", errors="replace")
    current = None
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split(";", 1)[0].strip()
        if line.startswith("//"):
            continue
        if not line:
            continue
        label = re.fullmatch(r"\[(.*)\]", line)
        if label:
            current = label.group(1).strip().lower()
            continue
        if (section is None and current is not None) or (section is not None and current != section.lower()):
            continue
        if "=" in line and not line.startswith(("+", "-")):
            key, value = line.split("=", 1)
            col = raw.find("=") + 2 + len(value) - len(value.lstrip())
            try:
                if key.strip().lower() == "include_ini":
                    read_ini(_beside(value.strip().strip('"'), path), opts, _depth=_depth + 1)
                    continue
                apply_key(key, value, opts)
            except _Bad as e:
                raise SceneError(str(e), SourceLoc(str(path), n, col)) from None
            if key.strip().lower() == "input_file_name":
                opts.input_base = str(path.parent)
            continue
        for word in line.split():
            try:
                if word[0] in "+-":
                    apply_switch(word, opts)
                elif word.lower().endswith(".ini"):
                    read_ini(_beside(word, path), opts, _depth=_depth + 1)
                else:
                    opts.input, opts.input_base = word, str(path.parent)
            except _Bad as e:
                raise SceneError(str(e), SourceLoc(str(path), n, raw.find(word) + 1)) from None


def _beside(name: str, ini: Path) -> Path:
    """An INI file named inside ``ini``: as given, else next to ``ini``."""
    p = Path(name)
    return p if p.is_absolute() or p.exists() else ini.parent / p


def read_options(words: list[str], opts: PovOptions | None = None) -> PovOptions:
    """Command-line words in order: switches (``+W640``, ``-D``), ``Key=Value`` options, INI files
    (``file.ini`` or ``file.ini[section]``) and the scene (any other word)."""
    opts = PovOptions() if opts is None else opts
    for word in words:
        ini = re.fullmatch(r"(.+\.ini)(?:\[(.*)\])?", word, re.IGNORECASE)
        try:
            if word[:1] in "+-" and len(word) > 1:
                apply_switch(word, opts)
            elif ini:
                read_ini(ini.group(1), opts, ini.group(2))
            elif re.fullmatch(r"[A-Za-z_]+=.*", word):
                key, value = word.split("=", 1)
                apply_key(key, value, opts)
            else:
                opts.input, opts.input_base = word, None
        except _Bad as e:
            raise SceneError(f"{word}: {e}") from None
    return opts
