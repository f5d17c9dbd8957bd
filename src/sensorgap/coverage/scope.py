"""Model only what a scene needs: the scope of an evaluation, decided before it runs.

For the region a scenario spans (the bounding box of the target's positions in the vehicle
frame) and the sun directions it will see, ``scene_scope`` decides

* which sensors can see the region at all (their range sphere reaches the box; an
  ultrasonic sensor with 5.5 m range is never evaluated on a 200 m corridor);
* which cameras the sun can glare during the scenario (the direct-sun term is computed only
  for them, only at the steps where it applies);
* which bands the weather attenuates (the others use 0 dB/km without computing the ITU-R
  models).

Everything it leaves out contributes exactly nothing to the fused Pd, so scoped and full
evaluation are identical (tested, and measured by ``sensorgap tradeoff``). ``Scope.log``
says what was skipped and why.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.points import sensor_can_reach_box
from sensorgap.coverage.scene import Scene
from sensorgap.models.system import Sensor

F64 = NDArray[np.float64]


@dataclass
class Scope:
    """What an evaluation needs: the sensors to evaluate, the cameras that may be glared,
    the attenuated bands, and a log of what was left out (sensor id -> reason)."""

    sensors: list[Sensor]
    glared: list[str] = field(default_factory=list)
    attenuated_bands: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)


def scene_scope(scene: Scene, lo: F64, hi: F64, sun_dirs: F64 | None = None) -> Scope:
    """The scope of evaluating ``scene`` on the box ``[lo, hi]`` (vehicle frame, m, x y z)
    with the given per-step sun directions ((N, 3), NaN rows: no sun)."""
    sensors, skipped, glared = [], {}, []
    for s in scene.sensors:
        if not sensor_can_reach_box(s, np.asarray(lo), np.asarray(hi)):
            skipped[s.id] = (
                f"{s.type_name} range {s.mount.max_range:g} m cannot reach the scenario's region"
            )
            continue
        sensors.append(s)
        if (
            sun_dirs is not None
            and len(sun_dirs)
            and np.any(s.model.glare_weights(s.mount, sun_dirs) > 0.0)
        ):
            glared.append(s.id)
    bands = []
    for s in sensors:
        band = s.model.band()
        label = band.kind if band.kind != "optical" else f"optical {band.wavelength_m:g} m"
        if scene.conditions.attenuation_db_km(band) > 0.0 and label not in bands:
            bands.append(label)
    return Scope(sensors, glared, bands, skipped)
