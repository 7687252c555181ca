"""The ``barsynth`` command line: a thin shell over the library.

Every bad input (unknown model, preset or parameter, a value out of range, an
unreadable file) ends in one line on stderr naming the parameter, the value, the
allowed range and the unit, exit status 2, and no file written. Ctrl-C ends in one line
(``barsynth: interrupted; nothing written`` during a render) and exit status 130, and no file
(not even a temporary one). A reader of standard output that goes away before the end
(``barsynth render twang -o - | head -c 10``, ``barsynth params twang | head -1``) ends the
command quietly with exit status 141 (128 + SIGPIPE, what a shell reports for a program that
SIGPIPE stopped): no message, since the reader chose to stop, but not 0, since the output was
cut. Warnings (a parameter given without effect, ``--duration auto`` at its cap) are one line
each on stderr; a progress line appears only when stderr is a terminal, and is cut to its width.
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


INTERRUPTED_STATUS = 130  # 128 + SIGINT, as shells report a process that Ctrl-C stopped
BROKEN_PIPE_STATUS = 141  # 128 + SIGPIPE, as shells report a process whose reader went away


class _Interrupted(Exception):
    """Ctrl-C: one line (this text) on stderr and exit status 130."""


class _ReaderGone(Exception):
    """Standard output's reader went away (a BrokenPipeError, which click would end in status 1):
    exit status 141 and no message."""


def _fail(message: str) -> None:
    """One line on stderr (any run of more than 80 characters without a space, such as a value
    click quotes, shortened: nothing a user typed is echoed at length), then exit status 2."""
    import re

    message = re.sub(r"\S{81,}", lambda run: show_text(run.group()), " ".join(str(message).split()))
    click.echo(f"barsynth: error: {message}", err=True)
    sys.exit(2)


def _interrupted(message: str) -> None:
    """One line on stderr, then exit status 130."""
    if sys.stderr.isatty():  # over the terminal's ^C (and any progress line)
        sys.stderr.write("\r\033[K")
    click.echo(f"barsynth: {message}", err=True)
    sys.exit(INTERRUPTED_STATUS)


def _warn(message: str) -> None:
    click.echo(f"barsynth: warning: {message}", err=True)


class _Group(click.Group):
    """One line and exit status 2 for every refusal: barsynth's own errors, click's
    usage errors (a bad option value, a missing argument) and failures to write."""

    def make_context(self, *args: Any, **kwargs: Any) -> click.Context:
        try:
            return super().make_context(*args, **kwargs)
        except BrokenPipeError:  # (--help into `| head -1`) before click ends it in status 1
            raise _ReaderGone from None

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:  # before click turns it into Abort (after a blank line)
            raise _Interrupted("interrupted") from None
        except BrokenPipeError:  # the reader went away (`barsynth params twang | head -1`)
            raise _ReaderGone from None

    def main(self, *args: Any, **kwargs: Any) -> Any:
        kwargs["standalone_mode"] = False
        try:
            result = super().main(*args, **kwargs)
        except _Interrupted as exc:
            _interrupted(str(exc))
        except click.UsageError as exc:
            _fail(exc.format_message())
        except click.Abort as exc:
            if isinstance(exc.__cause__, KeyboardInterrupt):  # Ctrl-C while click parsed the options
                _interrupted("interrupted")
            _fail("aborted")
        except BarsynthError as exc:
            _fail(str(exc))
        except _ReaderGone:
            _quiet_stdout()
            sys.exit(BROKEN_PIPE_STATUS)
        except OSError as exc:  # stdout itself failed, e.g. a full disk
            _fail(f"could not write output: {exc.strerror or exc}")
        sys.exit(result if isinstance(result, int) else 0)


def _quiet_stdout() -> None:
    """Point standard output at /dev/null, so what is left in its buffer goes nowhere at exit
    (not into a traceback about the broken pipe)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    except (AttributeError, ValueError, OSError):  # no standard output to point anywhere
        pass
    finally:
        os.close(devnull)


def _json_out(data: Any) -> None:
    """``data`` as JSON on stdout (NumPy values as numbers, inf and NaN as null: jsonout)."""
    import json

    from .jsonout import json_ready

    click.echo(json.dumps(json_ready(data), indent=2, allow_nan=False))


class _Whole(click.ParamType):
    """A whole number option, checked as it is parsed: a bad one is barsynth's one line
    (``parameter count = 'abc' is not a whole number; allowed: 1 to 1000 modes (a whole number)``),
    not click's "Invalid value". ``label`` names it in messages (default: the option's name)."""

    name = "integer"

    def __init__(self, minimum: int, maximum: int | None = None, unit: str = "", *, label: str | None = None):
        self.minimum, self.maximum, self.unit, self.label = minimum, maximum, unit, label

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        from .checks import check_whole

        number = value
        if isinstance(value, str):
            try:
                number = int(value.strip())
            except ValueError:
                try:
                    number = float(value)  # 3.0 and 1e3 are whole; 2.5, nan and inf are not
                except ValueError:
                    number = value
        return check_whole(self.label or _param_name(param), number, self.unit, self.minimum, self.maximum,
                           integral_floats=True)


class _Real(click.ParamType):
    """A number option, checked as it is parsed (a finite number in the range, with the unit in
    the message), as :class:`_Whole`."""

    name = "float"

    def __init__(self, unit: str, *, minimum: float | None = None, minimum_exclusive: bool = False):
        self.unit, self.minimum, self.minimum_exclusive = unit, minimum, minimum_exclusive

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        from .checks import check_number

        return check_number(_param_name(param), value, self.unit, minimum=self.minimum,
                            minimum_exclusive=self.minimum_exclusive, parse_text=True)


class _Choice(click.Choice):
    """A choice option whose refusal is barsynth's one line
    (``parameter bc = 'nope' is not a known choice; allowed: one of free-free, ...``).
    ``choices`` may be a function returning them, called when first needed (so a table in
    a module that imports NumPy is not imported with the command line)."""

    def __init__(self, choices: Any, *, label: str | None = None):
        self._load = choices if callable(choices) else None
        super().__init__(() if callable(choices) else choices)
        self.label = label

    @property
    def choices(self) -> tuple[Any, ...]:
        if self._load is not None:
            self._choices, self._load = tuple(self._load()), None
        return self._choices

    @choices.setter
    def choices(self, value: Any) -> None:
        self._choices = tuple(value)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            from .checks import show_value

            raise ParameterError(f"parameter {self.label or _param_name(param)} = {show_value(value)} is not a "
                                 f"known choice; allowed: one of {', '.join(map(str, self.choices))}") from None


def _param_name(param: click.Parameter | None) -> str:
    return "value" if param is None or param.name is None else param.name


def _shown(value: Any) -> str:
    """A parameter value as people write it: 0.3, 6.9e+10, 1,4,10 (a list), - (an empty one)
    (a table's rows show theirs with :meth:`~barsynth.parameters.Parameter.shown`)."""
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
_POSITIVE_PA = _Real("Pa", minimum=0.0, minimum_exclusive=True)
_POSITIVE_KG_M3 = _Real("kg/m^3", minimum=0.0, minimum_exclusive=True)
_POSITIVE_M = _Real("m", minimum=0.0, minimum_exclusive=True)


def _material_options(command: Any) -> Any:
    """--material, or --youngs-modulus and --density, and --length."""
    for option in reversed([
        click.option("--material", metavar="NAME", help="A material from `barsynth materials`."),
        click.option("--youngs-modulus", "youngs_modulus_pa", type=_POSITIVE_PA, metavar="PA",
                     help="Young's modulus E in Pa (instead of --material)."),
        click.option("--density", "density_kg_m3", type=_POSITIVE_KG_M3, metavar="KG_M3",
                     help="Density rho in kg/m^3 (instead of --material)."),
        click.option("--length", "length_m", type=_POSITIVE_M, required=True, metavar="M", help="Bar length L in m."),
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


_THEORY_HELP = ("Bar theory: euler-bernoulli (thin bar, the default) or timoshenko (shear and rotary inertia: "
                "thick bars, woods; needs a shear modulus, from --material, --poisson or --shear-modulus).")


def _shear_options(command: Any) -> Any:
    """--theory, --poisson, --shear-modulus and --shear-coefficient."""
    def theories() -> tuple[str, ...]:
        from .physics.theory import THEORIES

        return THEORIES

    for option in reversed([
        click.option("--theory", type=_Choice(theories), default="euler-bernoulli", show_default=True,
                     help=_THEORY_HELP),
        click.option("--poisson", "poisson_ratio", type=_Real("(dimensionless)"), metavar="NU",
                     help="Poisson's ratio nu (isotropic bar): G = E / (2 (1 + nu)), kappa Cowper's value "
                          "10 (1 + nu) / (12 + 11 nu). Overrides the material's shear data; not with --shear-modulus."),
        click.option("--shear-modulus", "shear_modulus_pa", type=_POSITIVE_PA, metavar="PA",
                     help="Shear modulus G in Pa (a wood: G_LT along the grain); kappa then 5/6. Overrides the "
                          "material's shear data; not with --poisson."),
        click.option("--shear-coefficient", "shear_coefficient", type=_Real("(dimensionless)"), metavar="KAPPA",
                     help="Shear coefficient kappa of the section (default: Cowper's from nu, else 5/6)."),
    ]):
        command = option(command)
    return command


def _shear_constants(theory: str, material: str | None, youngs_modulus_pa: float, poisson_ratio: float | None,
                     shear_modulus_pa: float | None, shear_coefficient: float | None) -> dict[str, Any]:
    """G, kappa and where nu came from, for --theory timoshenko: --poisson or --shear-modulus if given (either
    replaces the material's shear data as a whole), else the material's; refused with euler-bernoulli."""
    from .physics import material as lookup
    from .physics.theory import shear_constants

    given = [f"{name} = {value:g}" for name, value in (("poisson_ratio", poisson_ratio),
                                                        ("shear_modulus_pa", shear_modulus_pa),
                                                        ("shear_coefficient", shear_coefficient)) if value is not None]
    if theory != "timoshenko":
        if given:
            raise ParameterError(f"parameter {' and '.join(given)} given with theory = {theory}; allowed: only with "
                                 "--theory timoshenko (an Euler-Bernoulli bar has no shear)")
        return {}
    if poisson_ratio is None and shear_modulus_pa is None and material is not None:
        mat = lookup(material)
        poisson_ratio = mat.poisson_ratio
        shear_modulus_pa = None if mat.poisson_ratio is not None else mat.shear_modulus_pa
    g, kappa = shear_constants(youngs_modulus_pa=youngs_modulus_pa, poisson_ratio=poisson_ratio,
                               shear_modulus_pa=shear_modulus_pa, shear_coefficient=shear_coefficient)
    if g is None:
        raise ParameterError("parameter shear_modulus_pa is missing; theory = timoshenko needs the shear modulus G "
                             "in Pa: give --shear-modulus PA or --poisson NU (or --material NAME)")
    return {"poisson_ratio": poisson_ratio, "shear_modulus_pa": g, "shear_coefficient": kappa}


_PROFILE_HELP = ("Thickness profile: uniform (closed forms) or an undercut, parabolic or circular (grids, "
                 "Richardson extrapolated), with --undercut-depth and --undercut-width.")


@main.command()
@_material_options
@click.option("--thickness", "thickness_m", type=_POSITIVE_M, required=True, metavar="M",
              help="Thickness h in m (bending direction; the full thickness of an undercut bar).")
@click.option("--width", "width_m", type=_POSITIVE_M, default=0.04, show_default=True, metavar="M",
              help="Bar width in m (a uniform Euler-Bernoulli bar does not depend on it).")
@click.option("--bc", "bc", required=True,
              type=_Choice(["free-free", "clamped-free", "clamped-clamped", "pinned-pinned", "clamped-pinned"]),
              help="Boundary conditions at the two ends.")
@_shear_options
@click.option("--profile", "profile", type=_Choice(["uniform", "parabolic", "circular"]), default="uniform",
              show_default=True, help=_PROFILE_HELP)
@click.option("--undercut-depth", "undercut_depth", type=_Real("(fraction of the thickness)"), metavar="FRACTION",
              help="Depth of the undercut at the middle, as a FRACTION of the thickness (0 to 0.98; not metres: "
                   "as in tune-undercut and the fd model). Required by parabolic and circular.")
@click.option("--undercut-width", "undercut_width", type=_Real("(fraction of the length)"), metavar="FRACTION",
              help="Length of the undercut, as a fraction of the bar's length (default 0.6 with an undercut).")
@click.option("--count", type=_Whole(1, 1000, "modes"), default=6, show_default=True, help="Number of modes.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def modes(material, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, width_m, bc, theory, poisson_ratio,
          shear_modulus_pa, shear_coefficient, profile, undercut_depth, undercut_width, count, as_json):
    """Mode frequencies of a bar: uniform or undercut, Euler-Bernoulli or Timoshenko.

    lambda is the eigenvalue of a uniform Euler-Bernoulli bar of thickness h ringing at
    each frequency (the textbook lambda_n for a uniform bar in that theory). With
    --theory timoshenko each mode also shows its distance in cents from the Euler-Bernoulli
    bar of the same shape; JSON adds theory, width_m, profile, the shear constants and
    cents_from_euler_bernoulli.

    \b
    Examples:
      barsynth modes --material acrylic --length 0.3 --thickness 0.003 --bc free-free
      barsynth modes --material rosewood --length 0.4 --thickness 0.02 --width 0.05 --bc free-free --theory timoshenko
      barsynth modes --material rosewood --length 0.4 --thickness 0.02 --width 0.05 --bc free-free \\
          --theory timoshenko --profile parabolic --undercut-depth 0.62 --undercut-width 0.6
    """
    import math

    from .physics import bending_wave_constant
    from .physics.profiles import Profile
    from .physics.theory import bar_modes_hz

    youngs_modulus_pa, density_kg_m3 = _material_constants(material, youngs_modulus_pa, density_kg_m3)
    shear = _shear_constants(theory, material, youngs_modulus_pa, poisson_ratio, shear_modulus_pa, shear_coefficient)
    if profile == "uniform":
        given = [f"{name} = {value:g}" for name, value in (("undercut_depth", undercut_depth),
                                                            ("undercut_width", undercut_width)) if value is not None]
        if given:
            raise ParameterError(f"parameter {' and '.join(given)} given with profile = uniform; allowed: only with "
                                 "--profile parabolic or circular")
        cut = None
    else:
        if undercut_depth is None:
            raise ParameterError(f"parameter undercut_depth is missing; profile = {profile} needs --undercut-depth "
                                 "FRACTION (0 to 0.98 of the thickness)")
        cut = Profile(profile, depth=undercut_depth, width=0.6 if undercut_width is None else undercut_width)
    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
               thickness_m=thickness_m, width_m=width_m, bc=bc, count=count, profile=cut)
    freqs = bar_modes_hz(theory=theory, shear_modulus_pa=shear.get("shear_modulus_pa"),
                         shear_coefficient=shear.get("shear_coefficient"), **bar)
    # the Euler-Bernoulli eigenvalue of a uniform bar ringing at f: the textbook lambda for a thin uniform bar
    a = bending_wave_constant(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3,
                              thickness_m=thickness_m)
    lams = [length_m * math.sqrt(2.0 * math.pi * float(f) / a) for f in freqs]  # (L outside: L^2 can leave float range)
    if theory == "euler-bernoulli" and cut is None:
        from .physics import lambdas

        lams = [float(x) for x in lambdas(bc, count)]
    thin = bar_modes_hz(theory="euler-bernoulli", **bar) if theory == "timoshenko" else freqs
    cents = [1200.0 * math.log2(f / f0) for f, f0 in zip(freqs, thin)]
    if as_json:
        out = {
            "bc": bc,
            "youngs_modulus_pa": youngs_modulus_pa,
            "density_kg_m3": density_kg_m3,
            "length_m": length_m,
            "thickness_m": thickness_m,
            "lambdas": lams,
            "frequencies_hz": [float(f) for f in freqs],
            "ratios": [float(f / freqs[0]) for f in freqs],
            "theory": theory,
            "width_m": width_m,
            "profile": "uniform" if cut is None else {"kind": cut.kind, "undercut_depth": cut.depth,
                                                      "undercut_width": cut.width},
        }
        if theory == "timoshenko":
            out.update(shear, cents_from_euler_bernoulli=cents)
        _json_out(out)
        return
    click.echo(f"{bc} bar, L = {length_m:g} m, h = {thickness_m:g} m, "
               f"E = {youngs_modulus_pa:g} Pa, rho = {density_kg_m3:g} kg/m^3")
    if cut is not None or theory == "timoshenko":
        details = [f"width {width_m:g} m", cut.describe() if cut is not None else "uniform", theory]
        if theory == "timoshenko":
            details.append(f"G = {shear['shear_modulus_pa']:.4g} Pa, kappa = {shear['shear_coefficient']:.4f}")
        click.echo("  " + ", ".join(details))
    header = f"{'n':>3}  {'lambda':>10}  {'frequency (Hz)':>15}  {'ratio':>9}"
    click.echo(header + (f"  {'vs E-B (cents)':>14}" if theory == "timoshenko" else ""))
    for n, (lam, f, c) in enumerate(zip(lams, freqs, cents), start=1):
        click.echo(f"{n:>3}  {lam:>10.4f}  {f:>15.3f}  {f / freqs[0]:>9.4f}"
                   + (f"  {c:>14.1f}" if theory == "timoshenko" else ""))


@main.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON: every field of every material.")
def materials(as_json: bool) -> None:
    """The materials table: E, rho, shear (nu, G, E/G, kappa), typical Q, what each entry is and its source.

    Isotropic materials give Poisson's ratio nu (G = E / (2 (1 + nu)), kappa Cowper's value);
    woods give G along the grain (G_LT, quartersawn bars; kappa 5/6) and show nu as -.

    Any model that takes Young's modulus and density takes one by name:
    --set material=steel (see `barsynth params MODEL`).
    """
    from dataclasses import asdict

    from .physics import materials as all_materials

    table = all_materials()
    if as_json:
        _json_out([{**asdict(mat), "modulus_ratio": mat.modulus_ratio, "shear_coefficient": mat.shear_coefficient}
                   for mat in table.values()])
        return
    import textwrap

    click.echo(f"{'material':<17} {'E (Pa)':>9}  {'rho (kg/m^3)':>12}  {'nu':>5}  {'G (Pa)':>9}  {'E/G':>5}  "
               f"{'kappa':>6}  {'Q':>6}")
    for name, mat in table.items():
        q = f"{mat.typical_q:g}" if mat.typical_q else "-"
        nu = f"{mat.poisson_ratio:g}" if mat.poisson_ratio is not None else "-"
        click.echo(f"{name:<17} {mat.youngs_modulus_pa:>9.3g}  {mat.density_kg_m3:>12.0f}  {nu:>5}  "
                   f"{mat.shear_modulus_pa:>9.3g}  {mat.modulus_ratio:>5.1f}  {mat.shear_coefficient:>6.4f}  {q:>6}")
        click.echo(textwrap.fill(f"{mat.description.rstrip('.')}. Source: {mat.source}", 100,
                                 initial_indent=" " * 4, subsequent_indent=" " * 4, break_on_hyphens=False))


# -- models -----------------------------------------------------------------------------
class _ModelCommand(click.Command):
    """A command on a MODEL: its --help ends with the models, each with its one-line summary
    (imported only when the help is asked for)."""

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        from .models import get_model, model_names

        with formatter.section("Models"):
            formatter.write_dl([(name, get_model(name).summary) for name in model_names()])
        super().format_epilog(ctx, formatter)


def _model(name: str):
    from .jitstart import program_start
    from .models import get_model

    program_start()  # the program's, before its first kernel: spares SciPy and CFFI imports (see jitstart)
    return get_model(name)


def _resolve(model, preset: str | None, assignments: tuple[str, ...], *, warn_inactive: bool = True):
    """The model's parameters from a preset (shipped, or a FILE.toml) and the --set values on top.

    Each parameter the user gave that has no effect under the result gets one warning line on
    stderr: every --set, and each value of their own preset file that differs from the default
    (the studio saves every parameter), except the settings of another excitation (an instrument
    keeps its mallet for a strike beside its recorded attack: ``barsynth fit`` writes both); a
    shipped preset's values are not the user's."""
    from .parameters import parse_assignments
    from .presets import preset_file_parameters, preset_parameters

    table = model.table
    own_file: dict[str, Any] = {}
    layers = []
    if preset is not None and preset.lower().endswith(".toml"):
        own_file = preset_file_parameters(model.name, preset)
        layers.append(own_file)
    elif preset is not None:
        layers.append(preset_parameters(model.name, preset))
    assigned = parse_assignments(assignments)
    layers.append(assigned)
    resolved = table.resolve(*layers)
    if warn_inactive:
        given = [name for name, value in table.validate(own_file).items()
                 if value != table[name].default and table[name].reads != ("excitation",)]
        for name, when in table.inactive(resolved, dict.fromkeys([*given, *assigned])):
            _warn(f"{name} has no effect unless {when}")
    return resolved


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


@main.command(cls=_ModelCommand)
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
    import shutil
    import textwrap

    width = max(60, min(100, shutil.get_terminal_size().columns))
    indent = " " * 28
    click.echo(textwrap.fill(f"{model.name}: {model.summary}", width, subsequent_indent="  "))
    for p in model.table:
        # a long range (a material's dozen choices) wraps under itself, as does the doc
        head = f"  {p.name:<24} {p.shown(p.default):>10}  "
        click.echo(textwrap.fill(f"[{p.range_text()}]", width, initial_indent=head,
                                 subsequent_indent=" " * (len(head) + 1), break_on_hyphens=False))
        acts = p.when and not p.doc.startswith(p.when_text())  # (banded's bar rows say it first)
        doc = p.doc + (f" (acts only when {p.when_text()})" if acts else "")
        click.echo(textwrap.fill(doc, width, initial_indent=indent, subsequent_indent=indent,
                                 break_on_hyphens=False))


@main.command(cls=_ModelCommand)
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
    errors = model.errors_cents(resolved, sample_rate=rate) if model.reports_reference_errors else None
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
        click.echo(f"  {name:<24} {model.table[name].shown(value)}")
    error_head = f" {'error (cents)':>14}" if errors else ""
    click.echo(f"{'group':<18} {'frequency (Hz)':>15} {'gain':>8} {'T60 (s)':>9}{error_head}")
    for k, m in enumerate(found):
        error = f" {errors[k]:>14.2f}" if errors else ""
        click.echo(f"{m.group:<18} {m.frequency_hz:>15.3f} {m.gain:>8.4f} {m.t60_s:>9.3f}{error}")


def _check_writable_dir(path: Path, what: str, *, extensions: tuple[str, ...] = ()) -> None:
    """An output path: not an existing FIFO, device or folder, with one of ``extensions`` (if any
    are given), in a folder that exists and is writable."""
    from .checks import check_extension, check_output_file

    check_output_file(path, f"parameter {what} =")
    if extensions:
        check_extension(path, f"parameter {what} =", extensions)
    parent = path.resolve().parent
    if not parent.is_dir():
        raise ParameterError(f"parameter {what} = {show_text(path)}: folder {show_text(parent)} does not exist")
    if not os.access(parent, os.W_OK):
        raise ParameterError(f"parameter {what} = {show_text(path)}: folder {show_text(parent)} is not writable")


def _write_all(jobs: list[tuple[Path, Any]]) -> None:
    """Write every ``(path, write(tmp_path))`` job to a temporary file beside its target,
    then rename them all: a failure anywhere (or a Ctrl-C) leaves no new or partial file behind.
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
    except BaseException as exc:  # a Ctrl-C too: no temporary file is left behind
        for tmp, _ in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        if isinstance(exc, BarsynthError) or not isinstance(exc, Exception):
            raise
        target = temps[-1][1] if temps else jobs[0][0]
        reason = getattr(exc, "strerror", None) or str(exc).strip().splitlines()[-1]
        raise BarsynthError(f"could not write {show_text(target)}: {reason}; nothing written") from None


def _write_stdout(data: memoryview) -> None:
    """Write all of ``data`` to standard output (a binary write to a pipe may take only part of it:
    the rest is written again, so a reader that went away is a BrokenPipeError, not a short file)."""
    stdout = sys.stdout.buffer
    while data:
        data = data[stdout.write(data):]
    stdout.flush()


PROGRESS_AFTER_S = 2.0  # a render that takes longer than this shows its progress on a terminal
PROGRESS_EVERY_S = 0.1  # how often the progress line is redrawn


def _is_terminal(stream: Any) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no such method, or closed
        return False


class _Progress:
    """The progress line of a long render, on stderr and only on a terminal (``terminal``
    forces it either way): shown once the render has taken ``after_s``, redrawn in place at
    most every PROGRESS_EVERY_S, erased by :meth:`close`. (``after_s``: PROGRESS_AFTER_S.) Called as the render watcher:
    ``(done_s, total_s, below_peak_db)`` (see models.rendering.watching).

    The line is cut to one column less than the terminal's width, read at each redraw (a line
    that wrapped would leave its first rows behind, as ``\\r`` goes back to the start of the last
    row only)."""

    def __init__(self, stream: Any = None, *, terminal: bool | None = None, after_s: float | None = None):
        import time

        self.stream = sys.stderr if stream is None else stream
        self.on = _is_terminal(self.stream) if terminal is None else terminal
        self.clock = time.monotonic
        self.shown_at = self.clock() + (PROGRESS_AFTER_S if after_s is None else after_s)
        self.drawn = False

    def __call__(self, done_s: float, total_s: float | None, below_peak_db: float | None) -> None:
        now = self.clock()
        if not self.on or now < self.shown_at:
            return
        self.shown_at = now + PROGRESS_EVERY_S
        if total_s is not None:
            text = f"rendering {done_s:.1f} of {total_s:g} s ({100.0 * done_s / total_s:.0f} %)"
        else:
            from .models.rendering import AUTO_MAX_S, AUTO_QUIET_DB

            down = "" if below_peak_db is None else f", {max(0.0, -below_peak_db):.0f} of {AUTO_QUIET_DB:g} dB down"
            text = f"rendering {done_s:.1f} s{down} (auto, at most {AUTO_MAX_S:g} s)"
        line = f"barsynth: {text}"[:max(1, self._columns() - 1)]
        self.stream.write(f"\r{line}\033[K")
        self.stream.flush()
        self.drawn = True

    def _columns(self) -> int:
        """The width of the terminal the stream writes to (else $COLUMNS, else 80)."""
        import shutil

        try:
            columns = os.get_terminal_size(self.stream.fileno()).columns
        except (AttributeError, ValueError, OSError):  # no file descriptor, closed, or not a terminal
            columns = 0
        return columns or shutil.get_terminal_size().columns  # (a terminal may not know its width: 0)

    def close(self) -> None:
        if self.drawn:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self.drawn = False


class _CtrlCBetweenBlocks:
    """Within the block, a Ctrl-C (SIGINT) is noted and acted on after the block being rendered
    (:meth:`check`, called between blocks): a KeyboardInterrupt raised anywhere else could land
    inside numba compiling a kernel (the first render after install), which swallows it (a
    ctypes callback: "Exception ignored") or turns it into a RuntimeError. A second Ctrl-C acts at
    once. Only in the main thread (where Python delivers signals)."""

    def __init__(self) -> None:
        self.asked = False
        self.previous: Any = None

    def __enter__(self) -> _CtrlCBetweenBlocks:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self._note)
        return self

    def __exit__(self, *exc: Any) -> None:
        import signal

        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)

    def _note(self, signum: int, frame: Any) -> None:
        if self.asked:
            raise KeyboardInterrupt
        self.asked = True

    def check(self) -> None:
        if self.asked:
            raise KeyboardInterrupt


def _render_samples(model, resolved, *, duration: float | str, rate: float, seed: int, raw: bool):
    """The model's samples, rendered in blocks: a progress line on a terminal, Ctrl-C stops it
    (nothing is written), and a warning line when ``auto`` stops at its cap."""
    import warnings

    from .models.rendering import NeverQuietWarning, watching

    progress = _Progress()
    ctrl_c = _CtrlCBetweenBlocks()

    def watch(done_s: float, total_s: float | None, below_peak_db: float | None) -> None:
        progress(done_s, total_s, below_peak_db)
        ctrl_c.check()

    try:
        with warnings.catch_warnings(record=True) as caught, watching(watch), ctrl_c:
            warnings.simplefilter("always", NeverQuietWarning)
            samples = model.render(resolved, duration_s=duration, sample_rate=rate, seed=seed,
                                   normalize=not raw)
    except KeyboardInterrupt:
        raise _Interrupted("interrupted; nothing written") from None
    finally:
        progress.close()
    for warning in caught:
        if issubclass(warning.category, NeverQuietWarning):
            _warn(str(warning.message))
        else:  # anything else, as Python would have shown it
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    return samples


@main.command(cls=_ModelCommand)
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@click.option("--duration", "duration", default="auto", show_default=True, metavar="S|auto",
              help="Duration in seconds (up to 600), or auto: until the sound has fallen 90 dB below "
                   "its peak (a bowed sound: after the bow is lifted), at most 60 s, ending with a "
                   "20 ms fade.")
@_rate_option
@click.option("--seed", default=0, show_default=True, type=_Whole(0), metavar="N", help="Noise seed.")
@click.option("--raw", is_flag=True, help="Keep the model's own level (no peak normalisation to -1 dBFS).")
@click.option("--subtype", type=_Choice(SUBTYPES), default="PCM_24", show_default=True,
              help="Sample format of the file.")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), metavar="PNG",
              help="Also draw a waveform + spectrogram PNG.")
@click.option("-o", "--output", "output", required=True, metavar="FILE",
              type=click.Path(path_type=Path),
              help="Audio file to write (.wav, .flac, .ogg), or - for a WAV file on standard output.")
def render(model_name, preset, assignments, duration, sample_rate, seed, raw, subtype, plot_path, output):
    """Render a sound to an audio file.

    By default the sound lasts until it has died away (--duration auto). A render
    that takes a while shows its progress on a terminal; Ctrl-C stops it, writes
    nothing and exits with status 130.

    \b
    Examples:
      barsynth render twang --preset steel-30cm -o steel.wav
      barsynth render twang --set q=300 --set vibrato_rate_hz=5 --duration 3 -o wobble.wav
      barsynth render banded --preset marimba -o - | aplay
    """
    from .audio_io import output_format, output_subtype, write_audio
    from .models.rendering import AUTO, check_render_duration

    model = _model(model_name)
    resolved = _resolve(model, preset, assignments)
    rate = _sample_rate(sample_rate)
    seconds = check_render_duration(duration)
    to_stdout = str(output) == "-"
    if to_stdout:
        if sys.stdout is None or getattr(sys.stdout, "buffer", None) is None:  # `>&-`: Python found no stdout
            raise ParameterError("parameter output = - is standard output, which is closed; allowed: "
                                 "- only with standard output open and redirected to a file or a pipe")
        if _is_terminal(sys.stdout):
            raise ParameterError("parameter output = - is standard output, which is a terminal; allowed: "
                                 "- only with standard output redirected to a file or a pipe")
        fmt = "WAV"
    else:
        _check_writable_dir(output, "output")  # (a folder or a device first: /dev/null has no extension)
        fmt = output_format(output)
    if plot_path is not None:
        _check_writable_dir(plot_path, "plot", extensions=(".png",))
        require("plot", "--plot")
    import numpy as np

    file_subtype = output_subtype(fmt, subtype, rate, output.suffix or ".wav")
    samples = _render_samples(model, resolved, duration=seconds, rate=rate, seed=seed, raw=raw)
    # (non-finite or exploding samples were refused by the render: models.rendering.check_samples)
    if raw and np.max(np.abs(samples)) > 1.0 and subtype != "FLOAT":
        raise ParameterError("the raw render exceeds full scale; use --subtype FLOAT or drop --raw")
    jobs = [] if to_stdout else [(output, lambda tmp: write_audio(tmp, samples, rate, fmt=fmt, subtype=file_subtype))]
    if plot_path is not None:
        from .analysis import plot_sound

        title = f"{model.name}{' ' + preset if preset else ''}"
        jobs.append((plot_path, lambda tmp: plot_sound(samples, rate, tmp, title=title)))
    _write_all(jobs)
    if to_stdout:  # the sound and nothing else
        import io

        buffer = io.BytesIO()
        write_audio(buffer, samples, rate, fmt=fmt, subtype=file_subtype)
        _write_stdout(buffer.getbuffer())
        return
    length = f"auto: {samples.size / rate:.2f} s" if seconds == AUTO else f"{seconds:g} s"
    click.echo(f"wrote {output} ({length} at {rate:g} Hz)")


@main.command()
@click.argument("song_path", metavar="SONG.mid", type=click.Path(path_type=Path))
@click.option("--model", "model_name", default="banded", show_default=True, metavar="MODEL",
              help="What plays every channel the map does not name.")
@_preset_option
@click.option("--map", "map_path", type=click.Path(path_type=Path), metavar="MAP.toml",
              help="Channels and programs to models and presets (docs/midi-notes.md).")
@_rate_option
@click.option("--voices", default=16, show_default=True, type=_Whole(1, 256), metavar="N",
              help="Voices per instrument (notes beyond steal the oldest released, then the quietest).")
@click.option("--subtype", type=_Choice(SUBTYPES), default="PCM_24", show_default=True,
              help="Sample format of the file.")
@click.option("-o", "--output", "output", required=True, metavar="FILE", type=click.Path(path_type=Path),
              help="Audio file to write (.wav, .flac, .ogg).")
def midi(song_path, model_name, preset, map_path, sample_rate, voices, subtype, output):
    """Render a MIDI file: each channel on the model its map names, tails to silence.

    A long song shows its progress on a terminal; Ctrl-C stops it and writes nothing.

    \b
    Examples:
      barsynth midi song.mid --preset marimba -o song.wav
      barsynth midi song.mid --map band.toml --sample-rate 44100 -o song.flac
    """
    from .audio_io import output_format, output_subtype, write_audio
    from .midi import load_map, read_midi
    from .playing.song import render_song

    rate = _sample_rate(sample_rate)
    _check_writable_dir(output, "output")
    fmt = output_format(output)
    channel_map = load_map(map_path, model=model_name, preset=preset)
    song = read_midi(song_path, max_length_s=3600.0)
    file_subtype = output_subtype(fmt, subtype, rate, output.suffix)
    progress = _Progress()
    ctrl_c = _CtrlCBetweenBlocks()

    def watch(done_s: float, total_s: float | None) -> None:
        progress(done_s, total_s, None)
        ctrl_c.check()

    try:
        with ctrl_c:
            refused: list = []
            samples = render_song(song, channel_map, sample_rate=rate, voices=voices, watch=watch, refused=refused)
    except KeyboardInterrupt:
        raise _Interrupted("interrupted; nothing written") from None
    finally:
        progress.close()
    if refused:
        keys = sorted({note.key for note, _ in refused})
        channels = sorted({note.channel + 1 for note, _ in refused})
        first, reason = refused[0]
        _warn(f"{len(refused)} note{'s' if len(refused) > 1 else ''} left out (keys {keys[0]}-{keys[-1]}, channel"
              f"{'s' if len(channels) > 1 else ''} {', '.join(map(str, channels))}), the model cannot reach them; "
              f"the first, at {float(first.time):.3f} s: {reason}")
    from .models.rendering import normalize_peak

    samples = normalize_peak(samples)  # -1 dBFS, as render does
    _write_all([(output, lambda tmp: write_audio(tmp, samples, rate, fmt=fmt, subtype=file_subtype))])
    click.echo(f"wrote {output} ({samples.size / rate:.2f} s at {rate:g} Hz, {len(song.notes()) - len(refused)} notes)")


@main.command(cls=_ModelCommand)
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@click.option("--midi-in", "midi_port", metavar="PORT",
              help="Play from this MIDI port (its number, name, or a part of its name); an unknown one lists them.")
@click.option("--midi-virtual", "midi_virtual", metavar="NAME",
              help="Make a MIDI input port NAME:in for other programs to connect to, and play from it.")
@click.option("--midi-api", type=_Choice(("default", "jack", "alsa")), default="default", show_default=True,
              help="Which MIDI system the port is in.")
@click.option("--device", metavar="D", help="Audio output device (sounddevice's index or name; default: the system's).")
@_rate_option
@click.option("--voices", default=16, show_default=True, type=_Whole(1, 256), metavar="N", help="Voices.")
@click.option("--block", default=256, show_default=True, type=_Whole(16, 8192), metavar="N",
              help="Samples per audio block.")
@click.option("--lead", "lead_blocks", default=4, show_default=True, type=_Whole(1, 64, "blocks"), metavar="N",
              help="Blocks the synthesis thread keeps ahead of the audio (more: safer on a busy machine, later notes).")
@click.option("--velocity", default=100, show_default=True, type=_Whole(1, 127), metavar="V",
              help="Keyboard notes' MIDI velocity.")
@click.option("--hold", "hold_s", default=0.5, show_default=True, type=_Real("s", minimum=0.0, minimum_exclusive=True),
              metavar="S", help="How long a keyboard note is held before its note off (a terminal reports no key up).")
@click.option("--seconds", type=_Real("s", minimum=0.0, minimum_exclusive=True), metavar="S",
              help="Stop after S seconds (default: Escape or Ctrl-C stops).")
def play(model_name, preset, assignments, midi_port, midi_virtual, midi_api, device, sample_rate, voices, block,
         lead_blocks, velocity, hold_s, seconds):
    """Play a model through the computer's audio (PortAudio, JACK among its hosts) from MIDI or the keyboard.

    Without --midi-in or --midi-virtual the computer keyboard plays two octaves: z s x d c v g b
    h n j m are C4 to B4, q 2 w 3 e r 5 t 6 y 7 u i are C5 to C6, at --velocity, each held
    --hold seconds (a terminal reports no key releases); Escape or Ctrl-D quits (q is a note).
    When standard input is not a terminal the same characters are read from it, and its end
    stops the playing once the last note has rung. At start, a line on stderr gives the
    expected note-to-sound latency: PortAudio's output latency plus the ring's lead.

    \b
    Examples:
      barsynth play banded --preset marimba
      barsynth play banded --preset marimba --midi-in "Digital Piano"
      barsynth play ruler --midi-virtual barsynth --midi-api jack --device jack
    """
    import contextlib
    import signal
    import threading

    require("play", "barsynth play")
    if midi_port is not None and midi_virtual is not None:
        raise BarsynthError("give --midi-in PORT or --midi-virtual NAME, not both")
    from .playing.instrument import Instrument
    from .playing.keyboard import HELP, KeyboardInput
    from .playing.player import midi_input
    from .playing.player import play as run

    model = _model(model_name)
    resolved = _resolve(model, preset, assignments)
    rate = _sample_rate(sample_rate)
    instrument = Instrument(model, voices, parameters=model.table.as_dict(resolved), sample_rate=rate)
    chosen = int(device) if device is not None and device.isdigit() else device
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGHUP):  # a clean stop: clients closed in order (see playing.player)
        signal.signal(signum, lambda *_: stop.set())
    def echo(line: str) -> None:
        click.echo(line, err=True)

    with contextlib.ExitStack() as stack:  # closes the keyboard, then the MIDI client (after the stream)
        midi_in = keyboard = None
        if midi_port is not None or midi_virtual is not None:  # MIDI first, then the audio stream
            midi_in = stack.enter_context(midi_input(midi_port, virtual=midi_virtual, api=midi_api))
            source = f"MIDI from {midi_virtual + ':in' if midi_virtual else midi_port} ({midi_api})"
        else:
            keyboard = stack.enter_context(KeyboardInput(velocity=velocity, hold_s=hold_s))
            source = HELP if keyboard.is_terminal else (
                "standard input is not a terminal: reading keys from it (its end stops); " + HELP)
        try:
            counts = run(instrument, sample_rate=rate, device=chosen, block=block, lead_blocks=lead_blocks,
                         midi_in=midi_in, keyboard=keyboard, seconds=seconds, echo=echo, stop=stop, source=source)
        except KeyboardInterrupt:
            counts = None
    if counts is not None:
        echo(f"played {counts['blocks']} blocks, {counts['underruns']} samples missing, "
             f"{counts['late']} events late")


@main.command("tune-undercut")
@_material_options
@click.option("--thickness", "thickness_m", type=_POSITIVE_M, required=True, metavar="M",
              help="Full thickness h in m (bending direction).")
@click.option("--width", "width_m", type=_POSITIVE_M, default=0.04, show_default=True, metavar="M", help="Bar width in m.")
@click.option("--target-ratio", type=_Real("", minimum=1.0), default=4.0, show_default=True, metavar="R",
              help="The f2/f1 to tune to (4 marimba and vibraphone, 3 xylophone).")
@click.option("--profile", "profile", type=_Choice(["parabolic", "circular"]), default="parabolic",
              show_default=True, help="Shape of the undercut.")
@click.option("--undercut-width", type=_Real(""), default=0.6, show_default=True, metavar="FRACTION",
              help="Length of the undercut, as a fraction of the bar's length.")
@_shear_options
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def tune_undercut(material, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, width_m, target_ratio, profile,
                  undercut_width, theory, poisson_ratio, shear_modulus_pa, shear_coefficient, as_json):
    """The undercut depth that tunes a free-free bar's f2/f1, and f3/f1 there.

    With --theory timoshenko the bar is tuned as it really rings (shear and rotary
    inertia): a thick wooden bar tuned in Euler-Bernoulli rings flat of the target.

    \b
    Examples:
      barsynth tune-undercut --material rosewood --length 0.38 --thickness 0.02 --target-ratio 4
      barsynth tune-undercut --material rosewood --length 0.4 --thickness 0.02 --width 0.05 --theory timoshenko
    """
    from .models.fd import FD_TABLE
    from .physics.undercut import tune_undercut as tune

    youngs_modulus_pa, density_kg_m3 = _material_constants(material, youngs_modulus_pa, density_kg_m3)
    shear = _shear_constants(theory, material, youngs_modulus_pa, poisson_ratio, shear_modulus_pa, shear_coefficient)

    bar = {name: FD_TABLE[name].validate(value) for name, value in (
        ("youngs_modulus_pa", youngs_modulus_pa), ("density_kg_m3", density_kg_m3), ("length_m", length_m),
        ("thickness_m", thickness_m), ("width_m", width_m), ("undercut_width", undercut_width))}
    cut_width = bar.pop("undercut_width")
    tuned = tune(target_ratio=target_ratio, kind=profile, undercut_width=cut_width, theory=theory,
                 shear_modulus_pa=shear.get("shear_modulus_pa"), shear_coefficient=shear.get("shear_coefficient"),
                 **bar)
    settings = {**bar, "profile": profile, "undercut_depth": round(tuned.profile.depth, 6), "undercut_width": cut_width}
    if theory != "euler-bernoulli":  # the fd bar that rings as tuned: its theory and shear stiffness too
        settings["theory"] = theory
        settings["shear_modulus_pa"] = FD_TABLE["shear_modulus_pa"].validate(shear["shear_modulus_pa"])
        settings["shear_coefficient"] = FD_TABLE["shear_coefficient"].validate(shear["shear_coefficient"])
    if as_json:
        _json_out({**tuned.to_json(), **({"poisson_ratio": shear["poisson_ratio"]} if shear else {}),
                   "fd_parameters": settings})
        return
    shown = f" (G = {shear['shear_modulus_pa']:.4g} Pa, kappa = {shear['shear_coefficient']:.4f})" if shear else ""
    click.echo(f"{profile} undercut over {cut_width:g} of the length: depth {tuned.profile.depth:.4f} of the thickness "
               f"({tuned.profile.depth * bar['thickness_m'] * 1000:.2f} mm), {theory}{shown}")
    click.echo(f"{'mode':>4} {'frequency (Hz)':>15} {'ratio':>8}")
    for n, (f, r) in enumerate(zip(tuned.frequencies_hz, tuned.ratios), start=1):
        click.echo(f"{n:>4} {f:>15.3f} {r:>8.4f}")
    ratios = tuned.ratios
    click.echo(f"f2/f1 = {ratios[1]:.4f}" + (f", f3/f1 = {ratios[2]:.4f}" if ratios.size > 2 else ""))
    click.echo("hear it: barsynth render fd " + " ".join(f"--set {k}={_shown(v)}" for k, v in settings.items())
               + " -o tuned.wav")


@main.command("bow-map")
@click.argument("model_name", metavar="MODEL")
@_preset_option
@_set_option
@click.option("--velocities", "velocity_count", default=24, show_default=True, metavar="N",
              type=_Whole(2, 200, "values", label="velocities"),
              help="How many bow velocities, spread logarithmically over bow_velocity_m_s's range.")
@click.option("--forces", "force_count", default=16, show_default=True, metavar="N",
              type=_Whole(2, 200, "values", label="forces"),
              help="How many bow forces, spread logarithmically over bow_force_n's range.")
@click.option("--duration", "duration", default="2.0", show_default=True, metavar="S",
              help="How long each setting is bowed before its amplitude is read (1 to 30 s).")
@click.option("--sample-rate", "sample_rate", default="44100", show_default=True, metavar="HZ",
              help="Sample rate in Hz.")
@click.option("--json", "as_json", is_flag=True, help="Print the whole map as JSON.")
@click.option("-o", "--output", "output", required=True, metavar="PNG",
              type=click.Path(path_type=Path), help="The picture to write (.png).")
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
    resolved = _resolve(model, preset, assignments, warn_inactive=False)  # the map bows whatever is set
    rate = _sample_rate(sample_rate)
    try:
        seconds = float(duration)
    except ValueError:
        raise ParameterError(f"parameter duration = {duration!r} is not a number; allowed: 1 to 30 s") from None
    _check_writable_dir(output, "output", extensions=(".png",))
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
@click.option("--json", "as_json", is_flag=True, help="Print JSON (the whole note analysis).")
@click.option("--max-partials", default=24, show_default=True, type=_Whole(1, 500), help="Most partials to report.")
@click.option("--nominal-hz", "nominal_hz", type=_Real("Hz", minimum=0.0, minimum_exclusive=True), metavar="HZ",
              help="The pitch the note should have (a soundfont's root key): f0 is sought near it.")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), metavar="PNG",
              help="Also draw a waveform + spectrogram PNG with the partials marked.")
def analyze(path, as_json, max_partials, nominal_hz, plot_path):
    """Analyse a recorded note: f0, the sustained partials (ratio to f0, level, decay and how
    it was measured), the attack, and whether the sample is looped.

    \b
    Example:
      barsynth analyze marimba.wav --nominal-hz 261.63 --json
    """
    from .analysis import analyze_note
    from .audio_io import load_audio

    if plot_path is not None:
        _check_writable_dir(plot_path, "plot", extensions=(".png",))
        require("plot", "--plot")
    samples, rate = load_audio(path)
    note = analyze_note(samples, rate, nominal_hz=nominal_hz, max_partials=max_partials)
    if plot_path is not None:
        from .analysis import plot_sound

        marks = [p.as_partial() for p in (*note.below_f0, *note.partials)]
        _write_all([(plot_path, lambda tmp: plot_sound(samples, rate, tmp, title=path.name, partials=marks))])
    if as_json:
        _json_out({"file": str(path), **note.to_json()})
        return
    for line in _note_lines(str(path), note):
        click.echo(line)


def _note_lines(name: str, note: Any) -> list[str]:
    """The text report of :func:`analyze`."""
    def number(value: float | None, form: str, missing: str = "-") -> str:
        return missing if value is None else format(value, form)

    floor = f"{note.noise_floor_db:.1f} dB" if note.noise_floor_db is not None else "none"
    lines = [f"{name}: {note.duration_s:.3f} s at {note.sample_rate:g} Hz; onset {note.onset_s:.4f} s, "
             f"start {note.start_s:.4f} s; noise floor {floor}"]
    if note.f0_hz is None:
        lines.append(f"f0: none ({'; '.join(note.notes) or 'no sustained partials'})")
    else:
        how = (f"{note.f0_family} ratios explain {100.0 * note.f0_explained:.0f} % of the sustained energy"
               if note.f0_family else "no other partial at a known ratio")
        lines.append(f"f0: {note.f0_hz:.3f} Hz ({how})")
    a = note.attack
    if a.energy_db is None:
        lines.append("attack: none")
    else:
        lines.append(f"attack: {1000.0 * a.duration_s:.1f} ms, {a.energy_db:.1f} dB of the energy, "
                     f"centroid {number(a.centroid_hz, '.0f')} Hz")
    if note.looped:
        lines.append("looped: yes (the strongest partials do not decay within the file)")
    if not (note.partials or note.below_f0):
        return lines
    lines.append(f"{'frequency (Hz)':>14} {'ratio':>8} {'level (dB)':>10} {'T60 (s)':>8} {'decay':>9} "
                 f"{'range (dB)':>15} {'over (s)':>13} {'rms (dB)':>8}  notes")
    for below, p in [(True, q) for q in note.below_f0] + [(False, q) for q in note.partials]:
        d = p.decay
        notes = []
        if below:
            notes.append("below f0")
        if d.knee_s is not None:
            after = "no decay" if d.second_t60_s is None else f"T60 {d.second_t60_s:.3f} s"
            notes.append(f"knee {d.knee_s:.3f} s, then {after}")
        if p.doublet_hz is not None:
            notes.append(f"doublet with {p.doublet_hz:.3f} Hz")
        if p.beats:
            notes.append("beats")
        if d.sustains:
            notes.append("does not decay")
        lines.append(
            f"{p.frequency_hz:>14.3f} {p.ratio:>8.4f} {p.level_db:>10.1f} {number(p.t60_s, '.3f'):>8} "
            f"{d.method:>9} {d.range_start_db:>6.1f} to {d.range_end_db:>5.1f} "
            f"{d.range_start_s:>6.3f}-{d.range_end_s:<6.3f} {d.rms_db:>8.2f}  {', '.join(notes)}"
        )
    return lines


FIT_OPTIONS = {"banded": {"excitation": ("sample", "strike")},
               "twang": {"material": None, "thickness_m": float, "length_m": float},
               "fd": {"material": None, "thickness_m": float, "width_m": float, "bc": None, "points": int}}
"""What ``fit --set`` takes per model: a choice, a number, or (None) a word the fit checks."""


def _same_file(a: Path, b: Path) -> bool:
    """Do ``a`` and ``b`` name one file (the same path after links, or hard links of one)?"""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist yet: not the same file
        return False


def _refuse_overwriting(recording: Path, outputs: dict[str, Path | None]) -> None:
    """One line, before anything is read, when an output would replace the recording or another
    output (``fit -o x.toml --render in.wav`` must not destroy ``in.wav``)."""
    given = [(name, path) for name, path in outputs.items() if path is not None]
    for i, (name, path) in enumerate(given):
        if _same_file(path, recording):
            raise ParameterError(f"parameter {name} = {show_text(str(path))} is the recording itself; allowed: "
                                 "another file (the fit never replaces its recording)")
        for other, earlier in given[:i]:
            if _same_file(path, earlier):
                raise ParameterError(f"parameter {name} = {show_text(str(path))} is also the {other} file; "
                                     "allowed: a file of its own for each output")


def _fit_options(model: str, assignments: tuple[str, ...]) -> dict[str, Any]:
    from .checks import check_number, check_whole, show_value

    known = FIT_OPTIONS[model]
    options: dict[str, Any] = {}
    for text in assignments:
        name, sep, value = text.partition("=")
        name = name.strip()
        if not sep or name not in known:
            allowed = ", ".join(f"{k}=..." for k in known)
            raise ParameterError(f"parameter set = {show_value(text)} is not allowed for fit --model {model}; "
                                 f"allowed: NAME=VALUE with NAME one of {allowed}")
        kind = known[name]
        if isinstance(kind, tuple):
            if value not in kind:
                raise ParameterError(f"parameter {name} = {show_value(value)} is not a known choice; allowed: "
                                     f"one of {', '.join(kind)}")
            options[name] = value
        elif kind is float:
            options[name] = check_number(name, value, "m", minimum=0.0, minimum_exclusive=True, parse_text=True)
        elif kind is int:
            from .models.fd.table import FD_TABLE

            grid = {p.name: p for p in FD_TABLE}[name]
            typed = value.strip()
            number: Any = int(typed) if typed.lstrip("+-").isdigit() and len(typed) <= 12 else typed
            options[name] = check_whole(name, number, "nodes", int(grid.minimum), int(grid.maximum))
        else:
            options[name] = value.strip()
    if "material" in options:
        from .physics import material

        material(options["material"])  # one line for an unknown material
    if "bc" in options:
        from .physics import BOUNDARY_CONDITIONS

        if options["bc"] not in BOUNDARY_CONDITIONS:
            raise ParameterError(f"parameter bc = {show_value(options['bc'])} is not a known choice; allowed: one "
                                 f"of {', '.join(BOUNDARY_CONDITIONS)}")
    return options


@main.command()
@click.argument("path", metavar="RECORDING", type=click.Path(path_type=Path))
@click.option("--model", "model_name", default="banded", show_default=True,
              type=_Choice(("banded", "twang", "fd"), label="model"), help="The model to fit.")
@click.option("--max-modes", default=12, show_default=True, type=_Whole(1, 24, "modes"),
              help="Most partials to fit as modes (banded).")
@click.option("--nominal-hz", "nominal_hz", type=_Real("Hz", minimum=0.0, minimum_exclusive=True), metavar="HZ",
              help="The pitch the note is meant to have (e.g. a soundfont's root key), to settle f0.")
@click.option("--set", "-s", "assignments", multiple=True, metavar="NAME=VALUE",
              help="What the fit is given: banded excitation=sample|strike; twang material=, thickness_m= or "
                   "length_m=; fd material=, thickness_m=, width_m=, bc=, points= (repeatable).")
@click.option("-o", "--output", required=True, type=click.Path(path_type=Path), metavar="PRESET.toml",
              help="The preset file to write.")
@click.option("--json", "as_json", is_flag=True,
              help="Print JSON: the parameters and, per partial, recording against resynthesis.")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), metavar="PNG",
              help="Draw recording and resynthesis side by side (spectrograms, partials).")
@click.option("--render", "render_path", type=click.Path(path_type=Path), metavar="OUT.wav",
              help="Also write the resynthesis (at the recording's rate and peak).")
def fit(path, model_name, max_modes, nominal_hz, assignments, output, as_json, plot_path, render_path):
    """Fit a model to a recording and write a preset that sounds like it.

    The recording is analysed (as `barsynth analyze`), the model fitted to its partials, the fit
    rendered and compared with the recording partial by partial; the spectral distance (spec 7.3)
    is reported against that of one decaying sine at f0.

    \b
    Examples:
      barsynth fit marimba.wav -o marimba.toml --render again.wav
      barsynth render banded --preset marimba.toml --set frequency_hz=440 -o a4.wav
      barsynth fit ruler.wav --model twang --set material=acrylic -o ruler.toml --json
    """
    from .audio_io import output_format, output_subtype, write_audio
    from .checks import check_extension
    from .fitting import fit_recording
    from .fitting.recording import read_recording

    options = _fit_options(model_name, assignments)
    _check_writable_dir(output, "output", extensions=(".toml",))
    if plot_path is not None:
        _check_writable_dir(plot_path, "plot", extensions=(".png",))
        require("plot", "--plot")
    if render_path is not None:
        _check_writable_dir(render_path, "render")
        check_extension(render_path, "parameter render =", (".wav", ".flac", ".ogg"))
    _refuse_overwriting(path, {"output": output, "plot": plot_path, "render": render_path})
    recording = read_recording(path)
    for line in recording.warnings:
        _warn(line)
    rate = recording.sample_rate
    try:
        result = fit_recording(recording.samples, rate, model=model_name, max_modes=max_modes,
                               nominal_hz=nominal_hz, options=options)
    except (BarsynthError, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - never a traceback: one line, status 2, no file
        reason = " ".join(str(exc).split())[:200] or "no message"
        raise BarsynthError(f"could not fit {show_text(str(path))} with the {model_name} model "
                            f"({type(exc).__name__}: {reason}); nothing written") from None
    text = result.preset_toml()
    jobs: list[tuple[Path, Any]] = [(output, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))]
    heard = result.heard()
    if render_path is not None:
        fmt = output_format(render_path)
        subtype = output_subtype(fmt, "PCM_24", rate, render_path.suffix)
        jobs.append((render_path, lambda tmp: write_audio(tmp, heard, rate, fmt=fmt, subtype=subtype)))
    if plot_path is not None:
        from .fitting.plots import plot_fit

        jobs.append((plot_path, lambda tmp: plot_fit(result, tmp, title=path.name)))
    _write_all(jobs)
    if as_json:
        _json_out({"file": str(path), "preset": str(output), "warnings": list(recording.warnings),
                   **result.to_json()})
        return
    for line in _fit_lines(str(path), str(output), result):
        click.echo(line)


def _fit_lines(name: str, preset: str, result: Any) -> list[str]:
    """The text report of :func:`fit`."""
    def number(value: float | None, form: str) -> str:
        return "-" if value is None else format(value, form)

    verdict = "at most half the sine's: good" if result.distance_db <= 0.5 * result.baseline_db else (
        "closer than one sine" if result.distance_db < result.baseline_db else "no closer than one sine")
    lines = [f"{name}: {result.model} fitted, f0 {result.analysis.f0_hz:.3f} Hz; wrote {preset}",
             f"spectral distance {result.distance_db:.2f} dB (one decaying sine at f0: {result.baseline_db:.2f} dB; "
             f"{verdict})",
             f"{'recording (Hz)':>14} {'level (dB)':>10} {'T60 (s)':>8}   {'fit (Hz)':>10} {'cents':>7} "
             f"{'dB':>6} {'T60 %':>7}"]
    for c in result.comparison:
        t60 = None if c.t60_error is None else 100.0 * c.t60_error
        lines.append(f"{c.frequency_hz:>14.3f} {c.level_db:>10.1f} {number(c.t60_s, '.3f'):>8}   "
                     f"{number(c.resynthesis_hz, '.3f'):>10} {number(c.cents, '+.2f'):>7} "
                     f"{number(c.level_error_db, '+.1f'):>6} {number(t60, '+.1f'):>7}")
    modes = result.details.get("modes") or []
    if modes:  # twang and fd: each partial as the model's mode, and its residual
        lines.append(f"{'partial (Hz)':>14} {'model mode':>20} {'model (Hz)':>11} {'residual (cents)':>16}")
        for m in modes:
            label = f"{m['group']} {m['number']}" if "group" in m else f"mode {m['mode']}"
            lines.append(f"{m['frequency_hz']:>14.3f} {label:>20} {m['model_hz']:>11.3f} {m['cents']:>+16.3f}")
    if result.details.get("unmatched_hz"):
        lines.append("partials no mode of the model explains (Hz): "
                     + ", ".join(f"{f:.3f}" for f in result.details["unmatched_hz"]))
    shown = {k: v for k, v in result.parameters.items() if k != "attack_samples"}
    lines.append("parameters: " + ", ".join(f"{k}={_shown(v)}" for k, v in shown.items()))
    return lines


@main.command()
@click.argument("model_name", metavar="[MODEL]", required=False)
@click.option("--json", "as_json", is_flag=True,
              help="Print JSON: for each model, its presets with description, source and parameters.")
def presets(model_name: str | None, as_json: bool) -> None:
    """List the presets of one model, or of every model."""
    from .models import model_names
    from .presets import load_preset, preset_names

    names = [_model(model_name).name] if model_name else list(model_names())
    found = {name: {preset: load_preset(name, preset) for preset in preset_names(name)} for name in names}
    if as_json:
        _json_out({name: [{"name": preset, "description": doc["preset"].get("description", ""),
                           "source": doc["preset"].get("source", ""), "parameters": doc.get("parameters", {})}
                          for preset, doc in shipped.items()]
                   for name, shipped in found.items()})
        return
    for name, shipped in found.items():
        for preset, doc in shipped.items():
            click.echo(f"{name:<8} {preset:<24} {doc['preset'].get('description', '')}")


@main.command()
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 lets other machines use the studio.")
@click.option("--port", default=8050, show_default=True, type=_Whole(0, 65535), help="TCP port (0 picks a free one).")
def studio(host, port):
    """Every model in the browser: sliders that change the sound as it plays, pictures, WAV and preset downloads.

    Prints the address to open; Ctrl-C stops it. See docs/studio.md.
    Needs the web stack: pip install 'barsynth[studio]'.
    """
    require("studio", "barsynth studio")
    from .studio.server import serve

    serve(host=host, port=port, echo=click.echo)
    # Stopped: leave now. A picture worker killed in the middle of sending its result leaves
    # concurrent.futures' manager thread blocked reading the half-written reply, and the
    # interpreter's exit joins that thread forever (seen once in the suite: the studio never
    # exited after SIGTERM). Everything of ours is closed and flushed by now.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


@main.group()
def listen() -> None:
    """Listening tests (MUSHRA-style ratings and A/B): run one in the browser, report on it."""


@listen.command("serve")
@click.argument("config", metavar="TEST.toml", type=click.Path(path_type=Path))
@click.option("--results", "results", type=click.Path(path_type=Path), metavar="RESULTS.db",
              help="SQLite file for the answers (created if missing; default: TEST-results.db beside TEST.toml).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 lets other machines take the test.")
@click.option("--port", default=8000, show_default=True, type=_Whole(0, 65535), help="TCP port (0 picks a free one).")
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
@click.option("--csv", "csv_dir", type=click.Path(path_type=Path), metavar="DIR",
              help="Also write ratings.csv, ab.csv, summary.csv and pairwise.csv into DIR (created).")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), metavar="PNG",
              help="Also draw a box plot of the ratings per clip.")
@click.option("--holm", "holm_correction", is_flag=True, help="Holm-correct the pairwise p-values.")
def listen_report(results, csv_dir, plot_path, holm_correction):
    """Per-clip statistics, pairwise rank-sum marks and A/B identification rates."""
    from .listening.report import CSV_NAMES, box_plot, csv_tables, report_text, write_table
    from .listening.store import open_existing

    if plot_path is not None:
        _check_writable_dir(plot_path, "plot", extensions=(".png",))
        require("plot", "--plot")
    if csv_dir is not None:
        from .checks import check_output_file, file_kind

        if csv_dir.exists() and not csv_dir.is_dir():
            kind = "a file" if csv_dir.is_file() else file_kind(csv_dir.stat().st_mode)
            raise ParameterError(f"parameter csv = {show_text(csv_dir)} is {kind}; "
                                 "allowed: a folder, or a new name (the folder is created)")
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


@main.command()
@click.argument("spec_path", metavar="SPEC.toml", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out_dir", required=True, metavar="DIR", type=click.Path(path_type=Path),
              help="Folder for audio/, manifest.csv and .parquet, metadata.csv and spec.toml (made if missing).")
@click.option("--workers", default=None, type=_Whole(1, 1024), metavar="N",
              help="Local processes rendering items at once (default: one per core).")
@click.option("--resume", is_flag=True, help="Keep finished items of the same spec whose files match the "
                                              "manifest's hash; render the rest.")
@click.option("--dask-scheduler", "scheduler", default=None, metavar="ADDRESS",
              help="Render on the Dask cluster of this scheduler (tcp://HOST:PORT) instead of local processes; "
                   "DIR must be shared with its workers (e.g. NFS). Not with --workers.")
def batch(spec_path, out_dir, workers, resume, scheduler):
    """Render a batch of variations: one audio file per item and a manifest.

    The spec (TOML) names a model, a preset, a count, a seed and how each varied parameter
    varies (grid, list, random, mutate); see docs/batch.md. Random draws the model refuses
    are drawn again and counted. The same spec gives byte-identical files whatever the number
    of workers. A bad spec writes nothing; Ctrl-C leaves only whole files, and --resume goes on.

    \b
    Examples:
      barsynth batch twangs.toml -o twangs --workers 2
      barsynth batch twangs.toml -o twangs --resume
      barsynth batch twangs.toml -o /nfs/twangs --dask-scheduler tcp://10.0.0.5:8786
    """
    from .extras import require

    require("batch", "barsynth batch")
    from .batch.progress import BatchProgress
    from .batch.run import run_batch
    from .batch.spec import load_spec

    spec = load_spec(spec_path)
    text = spec_path.read_text(encoding="utf-8")
    if scheduler is not None and workers is not None:
        raise ParameterError(f"parameter workers = {workers} is not allowed with --dask-scheduler; allowed: one of "
                             "them (the cluster's workers render)")
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError(f"parameter output = {show_text(out_dir)} is not a folder; allowed: a folder, "
                             "made if missing")
    client = None
    if scheduler is not None:  # (connected before anything is written)
        from .batch.cluster import connect, disconnect

        client = connect(scheduler)
        click.get_current_context().call_on_close(lambda: disconnect(client))
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BarsynthError(f"could not create {show_text(out_dir)}: {exc.strerror or exc}") from None
    kept = []
    with BatchProgress() as progress:
        def watch(done, total):
            if not kept:  # the first call: the items a resume kept
                kept.append(done)
            progress(done, total)

        import signal

        # Ctrl-C or kill -INT stops a batch as it stops a render, even where the shell that
        # started it in the background left SIGINT ignored (Python then installs no handler)
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            rows = run_batch(spec, out_dir, workers=workers or os.cpu_count() or 1, resume=resume, spec_text=text,
                             progress=watch, scheduler=client)
        finally:
            signal.signal(signal.SIGINT, previous)
    refused = sum(1 for row in rows if row["error"])
    redrawn = sum(int(row["rejected"]) for row in rows)
    notes = [f"{kept[0]} kept"] if resume and kept else []
    notes += [f"{redrawn} refused draws redrawn"] if redrawn else []
    notes += [f"{refused} refused: see manifest.csv"] if refused else []
    click.echo(f"wrote {len(rows) - refused} items to {out_dir}" + (f" ({'; '.join(notes)})" if notes else ""))


if __name__ == "__main__":  # pragma: no cover
    main()
