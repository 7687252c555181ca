"""barsynth: physically derived synthesis of vibrating bars.

Import is kept light: models and analysis load on first use.
"""

__version__ = "0.1.0"

from .errors import AudioFileError, BarsynthError, ModelError, ParameterError, PresetError

__all__ = [
    "AudioFileError",
    "BarsynthError",
    "ModelError",
    "ParameterError",
    "PresetError",
    "__version__",
]
