"""The all-pass (generalised) waveguide bar: the model (:mod:`.voice`), its design (:mod:`.design`)
and its kernel (:mod:`.kernel`)."""

from .design import AllpassDesign, Filter, ModeFit, allpass_design
from .injection import response
from .voice import ALLPASS_TABLE, BOUNDARY_CONDITIONS, MODEL, AllpassModel, AllpassVoice, design_for

__all__ = ["ALLPASS_TABLE", "BOUNDARY_CONDITIONS", "MODEL", "AllpassDesign", "AllpassModel", "AllpassVoice",
           "Filter", "ModeFit", "allpass_design", "design_for", "response"]
