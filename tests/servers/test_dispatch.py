"""Type dispatch of a server's inputs: the first listed base class a message derives from."""

from __future__ import annotations

from overdrive.messages import GpsIns, Imu
from overdrive.servers.dispatch import TypeDispatch


class NoisyGps(GpsIns, frozen=True):
    """A subclass: handled as its base."""


def test_each_type_reaches_its_handler_subclasses_their_base_and_the_rest_the_default() -> None:
    seen: list[tuple[str, float, object]] = []
    dispatch = TypeDispatch(
        ((GpsIns, lambda t, m, out: seen.append(("gps", t, m))),
         (Imu, lambda t, m, out: seen.append(("imu", t, m)))),
        lambda t, m, out: seen.append(("other", t, m)))
    pose = {"x_m": 0.0, "y_m": 0.0, "heading_rad": 0.0, "speed_mps": 1.0, "pitch_rad": 0.0,
            "roll_rad": 0.0, "odometer_m": 0.0}
    gps, noisy = GpsIns(**pose), NoisyGps(**pose)
    imu = Imu(accel_x_mps2=0.0, accel_y_mps2=0.0, accel_z_mps2=9.8, yaw_rate_rps=0.0)
    status = object()
    for t, msg in enumerate((gps, noisy, imu, status, "not a message")):
        dispatch(float(t), msg, [])
    assert [s[0] for s in seen] == ["gps", "gps", "imu", "other", "other"]
    assert dispatch.handler_for(NoisyGps) is dispatch.handler_for(NoisyGps), "resolved once"
