"""A register-level model of the STM32F103C8 ("blue pill") on unicorn: see board-model/README.md."""

from .core import Chip  # noqa: F401
from .elf import Elf  # noqa: F401
