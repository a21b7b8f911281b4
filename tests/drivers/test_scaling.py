import math

import numpy as np
import pytest

from drivers.scaling import ChannelScaling


def test_travel_codes_span_the_sensor_range():
    sc = ChannelScaling()
    assert sc.travel_to_code([0.0, math.pi]).tolist() == [-32768, 32767]
    assert sc.code_to_travel([-32768, 32767]) == pytest.approx([0.0, math.pi])
    # Out-of-range travel clips like the resistive sensor.
    assert sc.travel_to_code([-0.1, 4.0]).tolist() == [-32768, 32767]


def test_travel_round_trip_within_half_lsb():
    sc = ChannelScaling()
    x = np.linspace(0, math.pi, 1001)
    back = sc.code_to_travel(sc.travel_to_code(x))
    assert np.max(np.abs(back - x)) <= sc.travel_lsb_rad / 2 + 1e-12


def test_vibration_is_symmetric_and_clips_at_full_scale():
    sc = ChannelScaling(vibration_full_scale_g=1000.0)
    assert sc.vibration_to_code([1000.0, -1000.0, 5000.0, 0.0]).tolist() == [32767, -32767, 32767, 0]
    assert sc.code_to_vibration([-32768, 32767]).tolist() == pytest.approx([-1000.0, 1000.0])


def test_from_breaker_reads_acquisition_keys(breaker):
    sc = ChannelScaling.from_breaker(breaker)
    assert sc.sample_rate_hz == 128000
    assert sc.travel_full_scale_rad == pytest.approx(3.14159)
    assert ChannelScaling.from_breaker(object()) == ChannelScaling()


def test_bad_scaling_is_refused_with_a_reason():
    with pytest.raises(ValueError, match="full scale"):
        ChannelScaling(travel_full_scale_rad=0.0)
    with pytest.raises(ValueError, match="sample rate"):
        ChannelScaling(sample_rate_hz=0)
