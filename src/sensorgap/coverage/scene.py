"""A scene: one system, target class and environment, with each sensor prepared once.

Preparation folds every constant of eq. 1-10 into dB and decides which effects apply
(e.g. glare only for cameras the sun can reach), so evaluation only pays for what the
scene needs. Sensors are prepared lazily: a sensor culled for a query is never prepared.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sensorgap.config.target import TargetConfig
from sensorgap.models.base import PreparedSensor
from sensorgap.models.conditions import Conditions
from sensorgap.models.system import Sensor, System


@dataclass
class Scene:
    """System + target + conditions.

    Attributes:
        system: the vehicle and its sensors.
        target: the target class evaluated.
        conditions: the resolved environment.
        log: what was evaluated, skipped and why (for summaries and audit reports).
    """

    system: System
    target: TargetConfig
    conditions: Conditions
    log: dict[str, list[str]] = field(default_factory=lambda: {"skipped": [], "effects": []})
    _prepared: dict[str, PreparedSensor] = field(default_factory=dict, repr=False)

    @property
    def sensors(self) -> tuple[Sensor, ...]:
        """All sensors of the system, in file order."""
        return self.system.sensors

    @property
    def roc_shift_db(self) -> float:
        """The environment's ROC shift, dB."""
        return self.conditions.roc_shift_db

    def prepared(self, sensor: Sensor) -> PreparedSensor:
        """The sensor folded for this scene (computed on first use)."""
        ps = self._prepared.get(sensor.id)
        if ps is None:
            ps = sensor.model.prepare(sensor.mount, self.target, self.conditions)
            self._prepared[sensor.id] = ps
            for name, note in ps.effects.items():
                self.log["effects"].append(f"{sensor.id}: {name}: {note}")
        return ps

    def skip(self, sensor: Sensor, reason: str) -> None:
        """Record that ``sensor`` was not evaluated and why."""
        line = f"{sensor.id}: {reason}"
        if line not in self.log["skipped"]:
            self.log["skipped"].append(line)
