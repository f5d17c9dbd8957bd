"""Physical properties of the coverage (hypothesis where it helps)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgap.coverage import evaluate_points
from sensorgap.models import System
from tests.conftest import make_scene


@settings(max_examples=25, deadline=None)
@given(
    st.sampled_from(["pedestrian", "bike", "car", "truck"]),
    st.floats(min_value=-60.0, max_value=60.0),
)
def test_active_pd_non_increasing_with_range_clear(
    system_a: System, target: str, bearing_deg: float
) -> None:
    """Along any ray from an active sensor's mount, in clear air, Pd never increases."""
    scene = make_scene(system_a, target, "clear")
    for s in scene.sensors:
        if s.type_name == "camera":
            continue
        m = s.mount
        b = m.yaw + np.radians(bearing_deg) * 0.5 * m.hfov / np.pi
        r = np.linspace(0.01, m.max_range * 1.2, 400)
        pts = np.column_stack([m.x + r * np.cos(b), m.y + r * np.sin(b), np.full_like(r, m.z)])
        cov = evaluate_points(scene, pts)
        row = cov.sensor_ids.index(s.id)
        pd = cov.pd[row]
        inside = (r >= m.min_range) & (r <= m.max_range)
        assert np.all(np.diff(pd[inside]) <= 1e-12), s.id


def test_glare_lowers_only_the_cameras_it_reaches(system_a: System, system_b: System) -> None:
    rng = np.random.default_rng(3)
    pts = np.column_stack(
        [rng.uniform(-40, 150, 3000), rng.uniform(-30, 30, 3000), np.full(3000, 0.75)]
    )
    for system in (system_a, system_b):
        clear = make_scene(system, "car", "clear")
        glare = make_scene(system, "car", "glare_front_right")
        a, b = evaluate_points(clear, pts), evaluate_points(glare, pts)
        glared = {line.split(":")[0] for line in glare.log["effects"] if ": glare:" in line}
        assert glared, "the glare preset must reach at least one camera"
        for i, sid in enumerate(a.sensor_ids):
            sensor = system.sensors[i]
            if sid in glared:
                assert sensor.type_name == "camera"
                assert np.all(b.pd[i] <= a.pd[i] + 1e-15)
                assert np.any(b.pd[i] < a.pd[i])
            else:
                np.testing.assert_array_equal(a.pd[i], b.pd[i])
        assert np.all(b.fused <= a.fused + 1e-15)
