"""Filaments: what the slicer is told of each printing material (PrusaSlicer's keys).

The 3MF writer passes them on (:mod:`fabkit.fab.slicer`); the 3MF check holds the file to them.
"""

from __future__ import annotations

__all__ = ["FILAMENTS"]

#: Filament settings per material (PrusaSlicer keys): its name for the material, and the middle
#: of the nozzle and bed temperature ranges filament makers print on their spools (check yours).
FILAMENTS: dict[str, dict] = {
    "PLA": {"filament_type": "PLA", "temperature": 210, "first_layer_temperature": 215,
            "bed_temperature": 60, "first_layer_bed_temperature": 60},
    "PETG": {"filament_type": "PETG", "temperature": 240, "first_layer_temperature": 240,
             "bed_temperature": 80, "first_layer_bed_temperature": 80},
    # PrusaSlicer calls flexible filaments FLEX; a soft filament buckles in the extruder when it
    # is pushed fast: 3 mm^3/s is a common limit for TPU 95A
    "TPU": {"filament_type": "FLEX", "temperature": 230, "first_layer_temperature": 230,
            "bed_temperature": 50, "first_layer_bed_temperature": 50,
            "filament_max_volumetric_speed": 3},
}
