"""The ``barsynth`` command line: a thin shell over the library.

Every bad input (unknown model, preset or parameter, a value out of range, an
unreadable file) ends in one line on stderr naming the parameter, the value, the
allowed range and the unit, exit status 2, and no file written.
Heavy modules are imported inside the commands, so ``barsynth --help`` is quick.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import click

from .audio_io import SUBTYPES
from .checks import show_text
from .errors import BarsynthError, ParameterError
from .extras import require


def _fail(message: str) -> None:
    """One line on stderr (any run of more than 80 characters without a space, such as a value
    click quotes, shortened: nothing a user typed is echoed at length), then exit status 2."""
    import re

    message = re.sub(r"\S{81,}", lambda run: show_text(run.group()), " ".join(str(message).split()))
    click.echo(f"barsynth: error: {message}", err=True)
    sys.exit(2)


class _Group(click.Group):
    """One line and exit status 2 for every refusal: barsynth's own errors, click's
    usage errors (a bad option value, a missing argument) and failures to write."""

    def main(self, *args: Any, **kwargs: Any) -> Any:
        kwargs["standalone_mode"] = False
        try:
            result = super().main(*args, **kwargs)
        except click.UsageError as exc:
            _fail(exc.format_message())
        except click.Abort:
            _fail("aborted")
        except BarsynthError as exc:
            _fail(str(exc))
        except BrokenPipeError:  # the reader went away (`barsynth params twang | head -1`)
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - so the exit flush stays quiet
            sys.exit(1)
        except OSError as exc:  # stdout itself failed, e.g. a full disk
            _fail(f"could not write output: {exc.strerror or exc}")
        sys.exit(result if isinstance(result, int) else 0)


def _json_out(data: Any) -> None:
    import json

    click.echo(json.dumps(data, indent=2, allow_nan=False, default=_json_default))


def _json_default(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _shown(value: Any) -> str:
    """A parameter value as people write it: 0.3, 6.9e+10, 1,4,10 (a list), - (an empty one)."""
    if isinstance(value, tuple):
        return ",".join(f"{x:g}" for x in value) or "-"
    return f"{value:g}" if isinstance(value, float) else str(value)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="barsynth", prog_name="barsynth")
def main() -> None:
    """barsynth: physically derived synthesis of vibrating bars.

    \b
    Examples:
      barsynth render twang --preset plastic-30cm -o twang.wav
      barsynth describe twang --set length_m=0.2 --json
      barsynth render banded --preset vibraphone --set excitation=bow -o bowed.wav
      barsynth bow-map banded --preset vibraphone -o bow-map.png
      barsynth analyze twang.wav --json
      barsynth studio
    """


# -- physics ----------------------------------------------------------------------------
def _material_options(command: Any) -> Any:
    """--material, or --youngs-modulus and --density, and --length."""
    for option in reversed([
        click.option("--material", metavar="NAME", help="A material from `barsynth materials`."),
        click.option("--youngs-modulus", "youngs_modulus_pa", type=float, metavar="PA",
                     help="Young's modulus E in Pa (instead of --material)."),
        click.option("--density", "density_kg_m3", type=float, metavar="KG_M3",
                     help="Density rho in kg/m^3 (instead of --material)."),
        click.option("--length", "length_m", type=float, required=True, metavar="M", help="Bar length L in m."),
    ]):
        command = option(command)
    return command


def _material_constants(material: str | None, youngs_modulus_pa: float | None,
                        density_kg_m3: float | None) -> tuple[float, float]:
    """E and rho from --material, or from --youngs-modulus and --density (not both)."""
    from . import physics

    if material is not None:
        if youngs_modulus_pa is not None or density_kg_m3 is not None:
            raise ParameterError("give either --material or --youngs-modulus and --density, not both")
        mat = physics.material(material)
        return mat.youngs_modulus_pa, mat.density_kg_m3
    if youngs_modulus_pa is None or density_kg_m3 is None:
        raise ParameterError("give --material NAME, or both --youngs-modulus PA and --density KG_M3")
    return youngs_modulus_pa, density_kg_m3


@main.command()
@_material_options
@click.option("--thickness", "thickness_m", type=float, required=True, metavar="M",
              help="Thickness h in m (bending direction).")
@click.option("--bc", "bc", required=True,
              type=click.Choice(["free-free", "clamped-free", "clamped-clamped", "pinned-pinned",
                                 "clamped-pinned"]),
              help="Boundary conditions at the two ends.")
@click.option("--count", type=int, default=6, show_default=True, help="Number of modes.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def modes(material, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, bc, count, as_json):
    """Mode frequencies of a uniform bar (Euler-Bernoulli).

    \b
    Example:
      barsynth modes --material acrylic --length 0.3 --thickness 0.003 --bc free-free
    """
    from . import physics

    youngs_modulus_pa, density_kg_m3 = _material_constants(material, youngs_modulus_pa, density_kg_m3)
    if not 1 <= count <= 1000:
        raise ParameterError(f"parameter count = {count} is out of range; allowed: 1 to 1000 modes")
    freqs = physics.bar_frequencies(
        youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3,
        length_m=length_m, thickness_m=thickness_m, bc=bc, count=count,
    )
    lams = physics.lambdas(bc, count)
    if as_json:
        _json_out({
            "bc": bc,
            "youngs_modulus_pa": youngs_modulus_pa,
            "density_kg_m3": density_kg_m3,
            "length_m": length_m,
            "thickness_m": thickness_m,
            "lambdas": [float(x) for x in lams],
            "frequencies_hz": [float(f) for f in freqs],
            "ratios": [float(f / freqs[0]) for f in freqs],
        })
        return
    click.echo(f"{bc} bar, L = {length_m:g} m, h = {thickness_m:g} m, "
               f"E = {youngs_modulus_pa:g} Pa, rho = {density_kg_m3:g} kg/m^3")
    click.echo(f"{'n':>3}  {'lambda':>10}  {'frequency (Hz)':>15}  {'ratio':>9}")
    for n, (lam, f) in enumerate(zip(lams, freqs), start=1):
        click.echo(f"{n:>3}  {lam:>10.4f}  {f:>15.3f}  {f / freqs[0]:>9.4f}")


@main.command()
def materials() -> None:
    """The materials table (E, rho, typical Q, source)."""
    from .physics import materials as all_materials

    for name, mat in all_materials().items():
        q = f"{mat.typical_q:g}" if mat.typical_q else "-"
        click.echo(f"{name:<16} E = {mat.youngs_modulus_pa:>9.3g} Pa  "
                   f"rho = {mat.density_kg_m3:>6.0f} kg/m^3  Q ~ {q:<5}  ({mat.source})")


# -- models -----------------------------------------------------------------------------
def _model(name: str):
    from .jitstart import defer_blas_probe
    from .models import get_model

    defer_blas_probe()  # before the first kernel runs: spares a SciPy import (see jitstart)
    return get_model(name)


def _resolve(model, preset: str | None, assignments: tuple[str, ...]):
    from .parameters import parse_assignments
    from .presets import preset_file_parameters, preset_parameters

    layers = []
    if preset is not None and preset.lower().endswith(".toml"):
        layers.append(preset_file_parameters(model.name, preset))
    elif preset is not None:
        layers.append(preset_parameters(model.name, preset))
    layers.append(parse_assignments(assignments))
    return model.table.resolve(*layers)


_preset_option = click.option("--preset", "-p", metavar="P", help="Start from a preset (see `barsynth presets`), "
                              "or from a preset file of your own (FILE.toml, as `barsynth studio` saves them).")
_set_option = click.option("--set", "-s", "assignments", multiple=True, metavar="NAME=VALUE",
                           help="Set a parameter (repeatable; a later --set of the same name "
                                "wins); see `barsynth params MODEL`.")
_rate_option = click.option("--sample-rate", "sample_rate", default="48000", show_default=True,
                            metavar="HZ", help="Sample rate in Hz.")


def _sample_rate(text: str) -> float:
    from .models.rendering import check_sample_rate

    return check_sample_rate(text)


@main.command()
@click.argument("model_name", metavar="MODEL")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--markdown", is_flag=True, help="Print a Markdown table (the docs are made with it).")
def params(model_name: str, as_json: bool, markdown: bool) -> None:
    """A model's parameter table: name, unit, range, default, doc."""
    model = _model(model_name)
    if as_json:
        _json_out(model.table.to_json())
        return
    if markdown:
        click.echo(model.table.to_markdown(), nl=False)
        return
    click.echo(f"{model.name}: {model.summary}")
    for p in model.table:
        click.echo(f"  {p.name:<24} {_shown(p.default):>10}  [{p.range_text()}]")
        click.echo(f"  {'':<24} {p.doc}")


@main.command()
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@_rate_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def describe(model_name, preset, assignments, sample_rate, as_json):
    """The resolved parameters and every mode the model will synthesise."""
    model = _model(model_name)
    resolved = _resolve(model, preset, assignments)
    rate = _sample_rate(sample_rate)
    found = model.describe(resolved, sample_rate=rate)
    # a reference model also says how far each mode is from the converged bar
    errors = model.errors_cents(resolved, sample_rate=rate) if hasattr(model, "errors_cents") else None
    if as_json:
        _json_out({
            "model": model.name,
            "sample_rate": rate,
            "parameters": model.table.as_dict(resolved),
            "modes": [m.to_json() | ({"error_cents": errors[k]} if errors else {}) for k, m in enumerate(found)],
        })
        return
    click.echo(f"{model.name} at {rate:g} Hz")
    for name, value in model.table.as_dict(resolved).items():
        click.echo(f"  {name:<24} {_shown(value)}")
    error_head = f" {'error (cents)':>14}" if errors else ""
    click.echo(f"{'group':<18} {'frequency (Hz)':>15} {'gain':>8} {'T60 (s)':>9}{error_head}")
    for k, m in enumerate(found):
        error = f" {errors[k]:>14.2f}" if errors else ""
        click.echo(f"{m.group:<18} {m.frequency_hz:>15.3f} {m.gain:>8.4f} {m.t60_s:>9.3f}{error}")


def _check_writable_dir(path: Path, what: str) -> None:
    """An output path: not an existing FIFO, device or folder, in a folder that exists and is writable."""
    from .checks import check_output_file

    check_output_file(path, f"parameter {what} =")
    parent = path.resolve().parent
    if not parent.is_dir():
        raise ParameterError(f"parameter {what} = {show_text(path)}: folder {show_text(parent)} does not exist")
    if not os.access(parent, os.W_OK):
        raise ParameterError(f"parameter {what} = {show_text(path)}: folder {show_text(parent)} is not writable")


def _write_all(jobs: list[tuple[Path, Any]]) -> None:
    """Write every ``(path, write(tmp_path))`` job to a temporary file beside its target,
    then rename them all: a failure anywhere leaves no new or partial file behind.
    A symbolic link is followed (its target is replaced); an existing file keeps its
    permissions, a new one gets the usual 0666 less the umask."""
    import tempfile

    from .checks import check_output_file

    for path, _ in jobs:  # a FIFO or device is never replaced by a file
        check_output_file(path, "output")
    umask = os.umask(0)
    os.umask(umask)
    temps: list[tuple[str, Path]] = []
    try:
        for path, write in jobs:
            target = path.resolve()
            mode = (target.stat().st_mode & 0o7777) if target.is_file() else (0o666 & ~umask)
            fd, tmp = tempfile.mkstemp(prefix=".barsynth-", suffix=path.suffix, dir=target.parent)
            os.close(fd)
            temps.append((tmp, target))
            os.chmod(tmp, mode)
            write(tmp)
        for tmp, path in temps:
            os.replace(tmp, path)
    except Exception as exc:
        for tmp, _ in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        if isinstance(exc, BarsynthError):
            raise
        target = temps[-1][1] if temps else jobs[0][0]
        reason = getattr(exc, "strerror", None) or str(exc).strip().splitlines()[-1]
        raise BarsynthError(f"could not write {show_text(target)}: {reason}; nothing written") from None


@main.command()
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@click.option("--duration", "duration", default="2.0", show_default=True, metavar="S",
              help="Duration in seconds.")
@_rate_option
@click.option("--seed", default=0, show_default=True, type=int, metavar="N", help="Noise seed.")
@click.option("--raw", is_flag=True, help="Keep the model's own level (no peak normalisation to -1 dBFS).")
@click.option("--subtype", type=click.Choice(SUBTYPES), default="PCM_24", show_default=True,
              help="Sample format of the file.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), metavar="PNG",
              help="Also draw a waveform + spectrogram PNG.")
@click.option("-o", "--output", "output", required=True, metavar="FILE",
              type=click.Path(dir_okay=False, path_type=Path), help="Audio file to write (.wav, .flac, .ogg).")
def render(model_name, preset, assignments, duration, sample_rate, seed, raw, subtype, plot_path, output):
    """Render a sound to an audio file.

    \b
    Examples:
      barsynth render twang --preset steel-30cm -o steel.wav
      barsynth render twang --set q=300 --set vibrato_rate_hz=5 --duration 3 -o wobble.wav
    """
    from .audio_io import output_format, output_subtype, write_audio
    from .models.rendering import check_duration

    model = _model(model_name)
    resolved = _resolve(model, preset, assignments)
    rate = _sample_rate(sample_rate)
    seconds = check_duration(duration)
    fmt = output_format(output)
    _check_writable_dir(output, "output")
    if plot_path is not None:
        if plot_path.suffix.lower() != ".png":
            raise ParameterError(f"parameter plot = {show_text(plot_path)} must end in .png")
        _check_writable_dir(plot_path, "plot")
        require("plot", "--plot")
    import numpy as np

    file_subtype = output_subtype(fmt, subtype, rate, output.suffix)
    samples = model.render(resolved, duration_s=seconds, sample_rate=rate, seed=seed,
                           normalize=not raw)
    # (non-finite or exploding samples were refused by the render: models.rendering.check_samples)
    if raw and np.max(np.abs(samples)) > 1.0 and subtype != "FLOAT":
        raise ParameterError("the raw render exceeds full scale; use --subtype FLOAT or drop --raw")
    jobs = [(output, lambda tmp: write_audio(tmp, samples, rate, fmt=fmt, subtype=file_subtype))]
    if plot_path is not None:
        from .analysis import plot_sound

        title = f"{model.name}{' ' + preset if preset else ''}"
        jobs.append((plot_path, lambda tmp: plot_sound(samples, rate, tmp, title=title)))
    _write_all(jobs)
    click.echo(f"wrote {output} ({seconds:g} s at {rate:g} Hz)")


@main.command("tune-undercut")
@_material_options
@click.option("--thickness", "thickness_m", type=float, required=True, metavar="M",
              help="Full thickness h in m (bending direction).")
@click.option("--width", "width_m", type=float, default=0.04, show_default=True, metavar="M", help="Bar width in m.")
@click.option("--target-ratio", type=float, default=4.0, show_default=True, metavar="R",
              help="The f2/f1 to tune to (4 marimba and vibraphone, 3 xylophone).")
@click.option("--profile", "kind", type=click.Choice(["parabolic", "circular"]), default="parabolic",
              show_default=True, help="Shape of the undercut.")
@click.option("--undercut-width", type=float, default=0.6, show_default=True, metavar="FRACTION",
              help="Length of the undercut, as a fraction of the bar's length.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def tune_undercut(material, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, width_m, target_ratio, kind,
                  undercut_width, as_json):
    """The undercut depth that tunes a free-free bar's f2/f1, and f3/f1 there.

    \b
    Example:
      barsynth tune-undercut --material rosewood --length 0.38 --thickness 0.02 --target-ratio 4
    """
    from .checks import check_number
    from .models.fd import FD_TABLE
    from .physics.undercut import tune_undercut as tune

    youngs_modulus_pa, density_kg_m3 = _material_constants(material, youngs_modulus_pa, density_kg_m3)

    bar = {name: FD_TABLE[name].validate(value) for name, value in (
        ("youngs_modulus_pa", youngs_modulus_pa), ("density_kg_m3", density_kg_m3), ("length_m", length_m),
        ("thickness_m", thickness_m), ("width_m", width_m), ("undercut_width", undercut_width))}
    check_number("target_ratio", target_ratio, "", minimum=1.0)
    cut_width = bar.pop("undercut_width")
    tuned = tune(target_ratio=target_ratio, kind=kind, undercut_width=cut_width, **bar)
    settings = {**bar, "profile": kind, "undercut_depth": round(tuned.profile.depth, 6), "undercut_width": cut_width}
    if as_json:
        _json_out({**tuned.to_json(), "fd_parameters": settings})
        return
    click.echo(f"{kind} undercut over {cut_width:g} of the length: depth {tuned.profile.depth:.4f} of the thickness "
               f"({tuned.profile.depth * bar['thickness_m'] * 1000:.2f} mm)")
    click.echo(f"{'mode':>4} {'frequency (Hz)':>15} {'ratio':>8}")
    for n, (f, r) in enumerate(zip(tuned.frequencies_hz, tuned.ratios), start=1):
        click.echo(f"{n:>4} {f:>15.3f} {r:>8.4f}")
    click.echo("hear it: barsynth render fd " + " ".join(f"--set {k}={_shown(v)}" for k, v in settings.items())
               + " -o tuned.wav")


@main.command("bow-map")
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@click.option("--velocities", "velocity_count", default=24, show_default=True, type=int, metavar="N",
              help="How many bow velocities, spread logarithmically over bow_velocity_m_s's range.")
@click.option("--forces", "force_count", default=16, show_default=True, type=int, metavar="N",
              help="How many bow forces, spread logarithmically over bow_force_n's range.")
@click.option("--duration", "duration", default="2.0", show_default=True, metavar="S",
              help="How long each setting is bowed before its amplitude is read (1 to 30 s).")
@click.option("--sample-rate", "sample_rate", default="44100", show_default=True, metavar="HZ",
              help="Sample rate in Hz.")
@click.option("--json", "as_json", is_flag=True, help="Print the whole map as JSON.")
@click.option("-o", "--output", "output", required=True, metavar="PNG",
              type=click.Path(dir_okay=False, path_type=Path), help="The picture to write (.png).")
def bow_map(model_name, preset, assignments, velocity_count, force_count, duration, sample_rate, as_json, output):
    """Where a bowed object sustains: bow velocity x bow force.

    Bows the object at every setting of a grid, reads the steady velocity at the
    bow point, and draws the region that sustains, with its least and greatest
    bow velocity for each force.

    \b
    Example:
      barsynth bow-map banded --preset vibraphone -o vibraphone-bow.png
    """
    require("plot", "barsynth bow-map")
    import numpy as np

    from .analysis.bowing import bow_map as measure_bow_map
    from .analysis.bowing import plot_bow_map

    model = _model(model_name)
    resolved = _resolve(model, preset, assignments)
    rate = _sample_rate(sample_rate)
    try:
        seconds = float(duration)
    except ValueError:
        raise ParameterError(f"parameter duration = {duration!r} is not a number; allowed: 1 to 30 s") from None
    for name, count in (("velocities", velocity_count), ("forces", force_count)):
        if not 2 <= count <= 200:
            raise ParameterError(f"parameter {name} = {count} is out of range; allowed: 2 to 200 values")
    if output.suffix.lower() != ".png":
        raise ParameterError(f"parameter output = {show_text(output)} must end in .png")
    _check_writable_dir(output, "output")
    table = model.table
    grid = {}
    if "bow_velocity_m_s" in table.names and "bow_force_n" in table.names:
        v, f = table["bow_velocity_m_s"], table["bow_force_n"]
        grid = {"velocities_m_s": np.geomspace(v.minimum, v.maximum, velocity_count),
                "forces_n": np.geomspace(f.minimum, f.maximum, force_count)}
    found = measure_bow_map(model, resolved, duration_s=seconds, sample_rate=rate, **grid)
    title = f"{model.name}{' ' + preset if preset else ''}: where bowing sustains (grey: it dies away)"
    _write_all([(output, lambda tmp: plot_bow_map(found, tmp, title=title))])
    if as_json:
        _json_out(found.to_json())
        return
    limits = found.velocity_limits()
    click.echo(f"{model.name}{' ' + preset if preset else ''}: sustains at {int(found.sustained.sum())} of "
               f"{found.sustained.size} settings")
    if limits:
        click.echo(f"{'force (N)':>10} {'least velocity (m/s)':>21} {'greatest velocity (m/s)':>24}")
        for force, low, high in limits:
            click.echo(f"{force:>10.3g} {low:>21.3g} {high:>24.3g}")
    click.echo(f"wrote {output}")


@main.command()
@click.argument("path", metavar="FILE", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--max-partials", default=24, show_default=True, type=int, help="Most partials to report.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), metavar="PNG",
              help="Also draw a waveform + spectrogram PNG with the partials marked.")
def analyze(path, as_json, max_partials, plot_path):
    """Find a sound's partials: frequency, level, T60, and ratios to the lowest."""
    import math

    from .analysis import find_partials, partial_ratios
    from .audio_io import load_audio
    from .jsonout import json_number

    if not 1 <= max_partials <= 500:
        raise ParameterError(f"parameter max_partials = {max_partials} is out of range; allowed: 1 to 500")
    if plot_path is not None:
        if plot_path.suffix.lower() != ".png":
            raise ParameterError(f"parameter plot = {show_text(plot_path)} must end in .png")
        _check_writable_dir(plot_path, "plot")
        require("plot", "--plot")
    samples, rate = load_audio(path)
    partials = find_partials(samples, rate, max_partials=max_partials)
    ratios = partial_ratios(partials) if partials else []
    if plot_path is not None:
        from .analysis import plot_sound

        _write_all([(plot_path, lambda tmp: plot_sound(samples, rate, tmp, title=path.name,
                                                        partials=partials))])
    if as_json:
        _json_out({
            "file": str(path),
            "sample_rate": rate,
            "duration_s": len(samples) / rate,
            "partials": [
                {
                    "frequency_hz": p.frequency_hz,
                    "level_db": json_number(p.level_db),
                    "t60_s": json_number(p.t60_s),
                    "ratio": float(r),
                }
                for p, r in zip(partials, ratios)
            ],
        })
        return
    click.echo(f"{path}: {len(samples) / rate:.3f} s at {rate:g} Hz, {len(partials)} partials")
    click.echo(f"{'frequency (Hz)':>15} {'ratio':>9} {'level (dB)':>11} {'T60 (s)':>9}")
    for p, r in zip(partials, ratios):
        t60 = f"{p.t60_s:.3f}" if math.isfinite(p.t60_s) else ("inf" if p.t60_s > 0 else "n/a")
        click.echo(f"{p.frequency_hz:>15.3f} {r:>9.4f} {p.level_db:>11.1f} {t60:>9}")


@main.command()
@click.argument("model_name", metavar="[MODEL]", required=False)
def presets(model_name: str | None) -> None:
    """List the presets of one model, or of every model."""
    from .models import model_names
    from .presets import load_preset, preset_names

    names = [_model(model_name).name] if model_name else list(model_names())
    for name in names:
        for preset in preset_names(name):
            info = load_preset(name, preset)["preset"]
            click.echo(f"{name:<8} {preset:<24} {info.get('description', '')}")


@main.command()
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 lets other machines use the studio.")
@click.option("--port", default=8050, show_default=True, type=int, help="TCP port (0 picks a free one).")
def studio(host, port):
    """Every model in the browser: sliders that change the sound as it plays, pictures, WAV and preset downloads.

    Prints the address to open; Ctrl-C stops it. See docs/studio.md.
    Needs the web stack: pip install 'barsynth[studio]'.
    """
    require("studio", "barsynth studio")
    from .studio.server import serve

    serve(host=host, port=port, echo=click.echo)


@main.group()
def listen() -> None:
    """Listening tests (MUSHRA-style ratings and A/B): run one in the browser, report on it."""


@listen.command("serve")
@click.argument("config", metavar="TEST.toml", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--results", "results", type=click.Path(dir_okay=False, path_type=Path), metavar="RESULTS.db",
              help="SQLite file for the answers (created if missing; default: TEST-results.db beside TEST.toml).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 lets other machines take the test.")
@click.option("--port", default=8000, show_default=True, type=int, help="TCP port (0 picks a free one).")
def listen_serve(config, results, host, port):
    """Run a listening test in the browser: MUSHRA pages and A/B pairs from TEST.toml.

    Every clip is loaded or rendered and checked before the server starts; each
    answer is written to RESULTS.db the moment it is submitted.
    Needs the web stack: pip install 'barsynth[studio]'.
    """
    require("studio", "barsynth listen serve")
    from .checks import check_input_file
    from .listening.server import serve
    from .listening.store import check_results_file

    if results is None:
        results = config.with_name(f"{config.stem}-results.db")
    check_input_file(config, "config")
    check_results_file(results)  # at once, before the clips are rendered; nothing is written
    serve(config, results, host=host, port=port, echo=click.echo)


@listen.command("report")
@click.argument("results", metavar="RESULTS.db", type=click.Path(path_type=Path))
@click.option("--csv", "csv_dir", type=click.Path(file_okay=False, path_type=Path), metavar="DIR",
              help="Also write ratings.csv, ab.csv, summary.csv and pairwise.csv into DIR (created).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), metavar="PNG",
              help="Also draw a box plot of the ratings per clip.")
@click.option("--holm", "holm_correction", is_flag=True, help="Holm-correct the pairwise p-values.")
def listen_report(results, csv_dir, plot_path, holm_correction):
    """Per-clip statistics, pairwise rank-sum marks and A/B identification rates."""
    from .listening.report import CSV_NAMES, box_plot, csv_tables, report_text, write_table
    from .listening.store import open_existing

    if plot_path is not None and plot_path.suffix.lower() != ".png":
        raise ParameterError(f"parameter plot = {show_text(plot_path)} must end in .png")
    if plot_path is not None:
        _check_writable_dir(plot_path, "plot")
        require("plot", "--plot")
    if csv_dir is not None:
        from .checks import check_output_file

        for name in CSV_NAMES:
            check_output_file(csv_dir / name, "parameter csv: file")
    with open_existing(results) as store:
        text = report_text(store, holm_correction=holm_correction)
        if csv_dir is not None:
            try:
                csv_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise BarsynthError(f"could not create {show_text(csv_dir)}: {exc.strerror or exc}") from None
            tables = csv_tables(store, holm_correction=holm_correction)
            _write_all([(csv_dir / name, lambda tmp, t=table: write_table(tmp, *t))
                        for name, table in tables.items()])
        if plot_path is not None:
            ratings = store.ratings_by_clip()
            if not ratings:
                raise ParameterError("parameter plot: the results file holds no ratings to plot")
            _check_writable_dir(plot_path, "plot")
            _write_all([(plot_path, lambda tmp: box_plot(ratings, tmp))])
    click.echo(text, nl=False)


if __name__ == "__main__":  # pragma: no cover
    main()
