"""Parameter tables (the single description of a model's controls) and preset files."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import pytest
from hypothesis import given
from hypothesis import strategies as st

from barsynth import ParameterError, PresetError
from barsynth import presets as preset_module
from barsynth.models import get_model, model_names
from barsynth.parameters import BOOL, CHOICE, FLOATS, INT, Compare, Parameter, ParameterTable, parse_assignments

TABLE = ParameterTable("demo_model", [
    Parameter("rate_hz", "Hz", 0.1, 1000.0, 10.0, "a log-scaled rate", scale="log"),
    Parameter("mix", "", 0.0, 1.0, 0.5, "a linear mix"),
    Parameter("count", "", 1, 12, 6, "a whole number", kind=INT),
    Parameter("on", "", None, None, False, "a switch", kind=BOOL),
    Parameter("mode", "", None, None, "a", "a choice", kind=CHOICE, choices=("a", "b")),
])


def test_resolve_layers_and_frozen_dataclass():
    p = TABLE.resolve({"rate_hz": "20"}, {"mix": 0.25, "on": "yes", "mode": "B"})
    assert (p.rate_hz, p.mix, p.count, p.on, p.mode) == (20.0, 0.25, 6, True, "b")
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.mix = 1.0  # type: ignore[misc]
    assert TABLE.as_dict(p)["rate_hz"] == 20.0
    assert type(p).__name__ == "DemoModelParameters"


@pytest.mark.parametrize("name,value,needles", [
    ("rate_hz", 0.05, ["rate_hz", "0.05", "0.1 to 1000 Hz"]),
    ("rate_hz", "fast", ["rate_hz", "fast", "not a number"]),
    ("rate_hz", float("nan"), ["rate_hz", "nan"]),
    ("rate_hz", True, ["rate_hz"]),
    ("count", 2.5, ["count", "whole number"]),
    ("count", 13, ["count", "1 to 12"]),
    ("on", "perhaps", ["on", "true or false"]),
    ("mode", "c", ["mode", "one of a, b"]),
    ("tempo", 1, ["unknown parameter", "tempo", "rate_hz"]),
])
def test_bad_values_name_parameter_value_and_range(name, value, needles):
    with pytest.raises(ParameterError) as info:
        TABLE.resolve({name: value})
    for needle in needles:
        assert needle in str(info.value)


@given(st.floats(min_value=0.0, max_value=1.0))
def test_unit_interval_round_trip(u):
    p = TABLE["rate_hz"]
    value = p.from_unit_interval(u)
    assert 0.1 <= value <= 1000.0
    assert p.to_unit_interval(value) == pytest.approx(u, abs=1e-9)


def test_log_scale_midpoint_is_the_geometric_mean():
    assert TABLE["rate_hz"].from_unit_interval(0.5) == pytest.approx(10.0)
    assert TABLE["mix"].from_unit_interval(0.5) == pytest.approx(0.5)


def test_table_rejects_inconsistent_definitions():
    with pytest.raises(ValueError):
        Parameter("x", "", 1.0, 2.0, 3.0, "default outside")
    with pytest.raises(ValueError):
        Parameter("x", "", 0.0, 2.0, 1.0, "log needs a positive minimum", scale="log")
    with pytest.raises(ValueError):
        ParameterTable("dup", [Parameter("a", "", 0, 1, 0.5, ""), Parameter("a", "", 0, 1, 0.5, "")])


def test_json_and_markdown_come_from_the_same_rows():
    rows = TABLE.to_json()
    assert [r["name"] for r in rows] == list(TABLE.names)
    assert rows[0] == {"name": "rate_hz", "unit": "Hz", "min": 0.1, "max": 1000.0, "default": 10.0,
                       "doc": "a log-scaled rate", "scale": "log", "kind": "float", "choices": None,
                       "max_items": None, "when": None, "when_text": None, "sets": None, "data": False}
    md = TABLE.to_markdown()
    assert md.count("\n") == len(TABLE) + 2
    assert "| `mode` | - | a / b | a |" in md


def test_parse_assignments():
    assert parse_assignments(["a=1", " b = x=y "]) == {"a": "1", "b": "x=y"}
    for bad in ("a", "=1"):
        with pytest.raises(ParameterError, match="NAME=VALUE"):
            parse_assignments([bad])


def test_preset_errors(tmp_path, monkeypatch):
    folder = tmp_path / "demo"
    folder.mkdir()
    (folder / "broken.toml").write_text("[parameters\nq = 1\n")
    (folder / "empty.toml").write_text("[preset]\ndescription = 'x'\n")
    (folder / "good.toml").write_text("[parameters]\nq = 100.0\n")
    monkeypatch.setattr(preset_module, "_folder", lambda model: tmp_path / model)
    assert preset_module.preset_names("demo") == ("broken", "empty", "good")
    assert preset_module.preset_parameters("demo", "good") == {"q": 100.0}
    with pytest.raises(PresetError, match="not valid TOML"):
        preset_module.load_preset("demo", "broken")
    with pytest.raises(PresetError, match=r"no \[parameters\]"):
        preset_module.load_preset("demo", "empty")
    with pytest.raises(PresetError, match="available: broken, empty, good"):
        preset_module.load_preset("demo", "missing")
    assert preset_module.preset_names("nothing-here") == ()


def test_a_floats_parameter_takes_lists_from_the_cli_toml_and_json():
    ratios = Parameter("ratios", "", 0.5, 100.0, (1.0, 4.0), "mode ratios", kind=FLOATS, max_items=4)
    assert ratios.validate("1, 3.99,9.2") == (1.0, 3.99, 9.2)
    assert ratios.validate([1, 2.5]) == (1.0, 2.5)
    assert ratios.validate("") == () and ratios.validate([]) == ()
    for bad, needle in [("1,200", "value 2 = '200' is out of range"), ("1,x", "'x' is not a number"),
                        ([1, 2, 3, 4, 5], "has 5 values"), (3.0, "is not a list"), ([1, True], "True"),
                        ("1,nan", "value 2 = 'nan' is not a finite number")]:
        with pytest.raises(ParameterError, match=needle) as info:
            ratios.validate(bad)
        assert "allowed: a list of up to 4 values, each 0.5 to 100 dimensionless" in str(info.value)
    assert ratios.to_json()["default"] == [1.0, 4.0] and ratios.to_json()["max_items"] == 4
    assert ratios.from_unit_interval(0.3) == (1.0, 4.0)
    table = ParameterTable("lists", [ratios])
    assert "| `ratios` | - | up to 4 values, each 0.5 to 100 | 1, 4 |" in table.to_markdown()
    with pytest.raises(ValueError):
        Parameter("bad", "", 1.0, 2.0, (3.0,), "out of range default", kind=FLOATS, max_items=2)
    # a record's own tuple of floats is checked at once, and refused with the same words
    for bad, needle in [((1.0, 200.0), "value 2 = 200.0 is out of range"), ((1.0, math.nan), "value 2 = nan"),
                        ((1.0,) * 5, "has 5 values")]:
        with pytest.raises(ParameterError, match=needle):
            ratios.validate(bad)
    given = (1.0, 2.5)
    assert ratios.validate(given) is given


def test_a_data_row_is_taken_as_any_row_and_shown_by_its_count():
    samples = Parameter("samples", "", -1.0, 1.0, (0.5, -0.5, 0.25), "a recording", kind=FLOATS, max_items=10,
                        data=True)
    table = ParameterTable("data", [samples, Parameter("rate_hz", "Hz", 1.0, 10.0, 2.0, "")])
    assert table.resolve({"samples": "0.1,0.2"}).samples == (0.1, 0.2)
    assert samples.to_json()["data"] is True and table["rate_hz"].to_json()["data"] is False
    assert samples.shown((0.1,) * 7) == "(7 values)" and table["rate_hz"].shown(2.0) == "2"
    assert "| `samples` | - | up to 10 values, each -1 to 1 | (3 values) |" in table.to_markdown()


@pytest.mark.parametrize("model_name,preset", [(m, p) for m in model_names() for p in preset_module.preset_names(m)])
def test_every_shipped_preset_resolves_and_sounds(model_name, preset):
    model = get_model(model_name)
    info = preset_module.load_preset(model_name, preset)["preset"]
    assert info.get("description")  # each says what it is
    x = model.render(preset_module.preset_parameters(model_name, preset), duration_s=0.2, sample_rate=44100,
                     normalize=False, dtype=np.float64)
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) > 0.0


def test_when_says_under_which_settings_a_parameter_acts():
    table = ParameterTable("x", [
        Parameter("excitation", "", None, None, "strike", "", kind=CHOICE, choices=("strike", "bow")),
        Parameter("bow_force_n", "N", 0.0, 10.0, 1.0, "bow force", when={"excitation": ("bow",)}),
    ])
    assert table.inactive(table.resolve()) == [("bow_force_n", "excitation = bow")]
    assert table.inactive(table.resolve({"excitation": "bow"})) == []
    assert table["bow_force_n"].to_json()["when"] == {"excitation": ["bow"]}
    with pytest.raises(ValueError, match="not a value it takes"):
        ParameterTable("y", [Parameter("a", "", 0.0, 1.0, 0.5, "", when={"excitation": ("bow",)})])


def test_when_compares_numbers_and_lengths_of_lists():
    table = ParameterTable("x", [
        Parameter("tuning", "", None, None, "physics", "", kind=CHOICE, choices=("physics", "ratios")),
        Parameter("rate_hz", "Hz", 0.0, 8.0, 0.0, "0 turns it off"),
        Parameter("depth_hz", "Hz", 0.0, 50.0, 18.0, "", when={"rate_hz": Compare(">", 0.0)}),
        Parameter("mode_count", "", 1, 24, 4, "", kind=INT),
        Parameter("ratios", "", 0.25, 200.0, (1.0, 4.0), "", kind=FLOATS, max_items=24),
        Parameter("t60s_s", "s", 0.005, 120.0, (), "", kind=FLOATS, max_items=24),
        Parameter("q", "", 3.0, 1e4, 300.0, "", when=[
            {"tuning": ("physics",), "t60s_s": Compare("<", "mode_count", count=True)},
            {"tuning": ("ratios",), "t60s_s": Compare("<", "ratios", count=True)}]),
    ])
    off = "rate_hz > 0"
    assert table.inactive(table.resolve()) == [("depth_hz", off)]
    assert table.inactive(table.resolve({"rate_hz": 0.1})) == []
    q_text = ("tuning = physics and t60s_s has fewer values than mode_count, "
              "or tuning = ratios and t60s_s has fewer values than ratios")
    for settings, q_acts in [({"t60s_s": "1,1,1"}, True), ({"t60s_s": "1,1,1,1"}, False),
                             ({"t60s_s": "1,1,1,1", "mode_count": 5}, True),
                             ({"tuning": "ratios", "t60s_s": "1,1,1,1"}, False),  # ratios: 2 modes
                             ({"tuning": "ratios", "t60s_s": "1"}, True),
                             ({"tuning": "ratios", "t60s_s": "1", "ratios": "1"}, False)]:
        found = table.inactive(table.resolve({"rate_hz": 1.0, **settings}))
        assert found == ([] if q_acts else [("q", q_text)]), settings
    assert table["q"].reads == ("mode_count", "ratios", "t60s_s", "tuning")


@pytest.mark.parametrize("model_name,row,values,acting,quiet", [
    # twang: the vibrato's depth without a rate, the short cantilever's settings and the free bar's
    # filters with their mix at 0
    ("twang", "vibrato_depth_hz", (5.0, 40.0), {"vibrato_rate_hz": 5.0}, {"vibrato_rate_hz": 0.0}),
    ("twang", "short_length_ratio", (0.5, 0.8), {}, {"short_cantilever_gain": 0.0}),
    ("twang", "slide", (False, True), {}, {"short_cantilever_gain": 0.0}),
    ("twang", "slide_time_s", (0.1, 0.5), {"slide": True}, {"slide": True, "short_cantilever_gain": 0.0}),
    ("twang", "noise_cutoff_hz", (1000.0, 8000.0), {}, {"free_bar_gain": 0.0}),
    ("twang", "free_band_q", (2.0, 50.0), {}, {"free_bar_gain": 0.0}),
    # banded: q once every mode has its own T60, by physics or by ratios
    ("banded", "q", (30.0, 1000.0), {"mode_count": 3, "mode_t60s_s": (1.0, 1.0)},
     {"mode_count": 3, "mode_t60s_s": (1.0, 1.0, 1.0)}),
    ("banded", "q", (30.0, 1000.0), {"tuning": "ratios", "mode_ratios": (1.0, 4.0, 9.0), "mode_t60s_s": (1.0,)},
     {"tuning": "ratios", "mode_ratios": (1.0, 4.0), "mode_t60s_s": (1.0, 0.5)}),
    # fd: the undercut's width at no depth
    ("fd", "undercut_width", (0.3, 0.8), {"profile": "parabolic", "undercut_depth": 0.3},
     {"profile": "parabolic", "undercut_depth": 0.0}),
])
def test_a_row_said_to_have_no_effect_has_none(model_name, row, values, acting, quiet):
    """What a row's "when" says, the sound shows: under ``quiet`` two values of the row render the
    same samples, bit for bit, under ``acting`` different ones."""
    model = get_model(model_name)
    table = model.table

    def render(settings, value):
        return model.render({**settings, row: value}, duration_s=0.6, sample_rate=24000, normalize=False,
                            dtype=np.float64, seed=3)

    assert table[row].acts_under(table.resolve(acting)) and not table[row].acts_under(table.resolve(quiet))
    assert not np.array_equal(render(acting, values[0]), render(acting, values[1]))
    assert np.array_equal(render(quiet, values[0]), render(quiet, values[1]))


def test_a_material_sets_youngs_modulus_and_density():
    from barsynth.models.rows import material_parameter
    from barsynth.physics import material

    table = ParameterTable("x", [Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 1e9, "E", scale="log"),
                                 Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 1000.0, "rho"),
                                 material_parameter()])
    steel = material("steel")
    p = table.resolve({"material": "steel"})
    assert (p.youngs_modulus_pa, p.density_kg_m3, p.material) == (steel.youngs_modulus_pa, steel.density_kg_m3, "steel")
    later = table.resolve({"material": "steel"}, {"density_kg_m3": 3000})  # a --set on top of a preset
    assert (later.youngs_modulus_pa, later.density_kg_m3, later.material) == (steel.youngs_modulus_pa, 3000.0, "custom")
    assert table.resolve(table.as_dict(p)) == p  # its resolved values round-trip (a saved preset)
    same = table.resolve({"material": "steel"}, {"density_kg_m3": steel.density_kg_m3})  # (a separate message)
    assert same.material == "steel"
    with pytest.raises(ParameterError, match="either material or density_kg_m3"):
        table.resolve({"material": "steel", "density_kg_m3": 3000})
    with pytest.raises(ParameterError, match="material"):
        table.resolve({"material": "unobtainium"})


def test_a_typed_record_is_checked_against_its_table():
    rows = [Parameter("length_m", "m", 0.1, 1.0, 0.3, "length"),
            Parameter("count", "", 1, 9, 2, "count", kind=INT),
            Parameter("shape", "", None, None, "bar", "", kind=CHOICE, choices=("bar", "ring"))]

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Good:
        length_m: float
        count: int
        shape: str

    table = ParameterTable("x", rows, record=Good)
    assert table.resolve({"count": 3}) == Good(length_m=0.3, count=3, shape="bar")

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class WrongType:
        length_m: float
        count: float
        shape: str

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class WrongOrder:
        count: int
        length_m: float
        shape: str

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class SameDefaults:
        length_m: float = 0.3
        count: int = 2
        shape: str = "bar"

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class OtherDefault:
        length_m: float = 0.3
        count: int = 3  # the row says 2
        shape: str = "bar"

    assert ParameterTable("x", rows, record=SameDefaults).resolve() == SameDefaults()
    for record in (WrongType, WrongOrder, OtherDefault):
        with pytest.raises(TypeError):
            ParameterTable("x", rows, record=record)
    with pytest.raises(TypeError, match="count has default 3; its table row's default is 2"):
        ParameterTable("x", rows, record=OtherDefault)


def test_a_material_row_tells_the_page_what_each_choice_sets():
    from barsynth.models import get_model
    from barsynth.physics import material

    row = next(r for r in get_model("banded").table.to_json() if r["name"] == "material")
    steel = material("steel")
    from barsynth.models.rows import material_shear

    assert row["sets"]["names"] == ["youngs_modulus_pa", "density_kg_m3", "shear_modulus_pa", "shear_coefficient"]
    assert row["sets"]["values"]["steel"] == [steel.youngs_modulus_pa, steel.density_kg_m3, *material_shear("steel")]
    assert "custom" not in row["sets"]["values"]


def test_every_exciter_declares_its_forms_and_its_rows_say_when_they_act():
    from barsynth.exciters import EXCITERS, Exciter

    assert set(EXCITERS) == {"strike", "pluck", "bow", "sample"}
    for name, exciter in EXCITERS.items():
        assert exciter.name == name and exciter.summary
        assert exciter.in_advance or exciter.coupled
        assert (exciter.force is not Exciter.force) == exciter.in_advance
        assert (exciter.coupling is not Exciter.coupling) == exciter.coupled
        assert (exciter.direct_sound is not Exciter.direct_sound) == exciter.direct
        for row in exciter.parameters():
            assert row.when == ((("excitation", (name,)),),)
    shared = {row.name: row.when for row in EXCITERS["strike"].parameters(also=("sample",))}
    assert shared["mallet_velocity_m_s"] == shared["mallet_mass_kg"] == ((("excitation", ("strike", "sample")),),)
    assert shared["mallet_hardness"] == ((("excitation", ("strike",)),),)


def test_an_exciter_must_implement_the_forms_it_declares():
    from barsynth.exciters import Exciter, Force

    with pytest.raises(TypeError, match="force"):
        type("Declared", (Exciter,), {"name": "declared", "in_advance": True})
    with pytest.raises(TypeError, match="coupling"):
        type("Undeclared", (Exciter,), {"name": "undeclared", "coupling": lambda self: None})
    with pytest.raises(TypeError, match="direct_sound"):
        type("Unheard", (Exciter,), {"name": "unheard", "direct": True, "in_advance": True,
                                     "force": lambda self, drive: None})

    class Tap(Exciter):
        name, summary, in_advance = "tap", "a unit impulse", True

        def force(self, drive):
            return Force(np.array([self.sample_rate]), 0.0)

    tap = Tap(None, 1000.0)
    assert tap.force(None).per_sample_n.tolist() == [1000.0] and tap.driven_until == 0
    with pytest.raises(NotImplementedError, match="tap"):
        tap.coupling()


def test_a_comparison_is_not_with_a_truth_value():
    from barsynth.parameters import Compare

    with pytest.raises(ValueError, match="finite number or a parameter"):
        Compare(">", True)
