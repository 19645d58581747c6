"""The robot's sensors (docs/model.md 13.5) without ROS: the IMU's specific force at rest (analytic), its noise
against the configured density and random walk (seeded), the encoders' quantization, the chamber pressure, the
suite's rates, and the messages as rosbags reads them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_msgs_py import bagio, codec, topics
from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Simulation
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.sensors import EncoderParameters, ImuParameters, PressureParameters, SensorParameters
from wallbot_sim.model.vacuum import ATMOSPHERE
from wallbot_sim.model.world import World
from wallbot_sim.sensors import Encoders, Imu, PressureSensor, SensorSuite, quantized
from wallbot_sim.sensors.suite import surface_gravity

G = RobotParameters().gravity
AT_REST = np.zeros(7)
VACUUM = {'chamber_area': 0.02, 'chamber_volume': 0.002, 'pump_max_pressure': 12000.0, 'pump_max_flow': 0.01,
          'leak_area': 2.0e-5}


def gravity(inclination: float) -> np.ndarray:
    return surface_gravity(Robot(RobotParameters(), World(inclination)))


def rest_reading(inclination: float, heading: float) -> tuple[np.ndarray, np.ndarray]:
    q = np.array([0.3, 0.2, heading, 0.0, 0.0, 0.0, 0.0])
    reading = Imu(ImuParameters(), gravity(inclination)).measure(q, AT_REST, AT_REST)
    return reading.angular_velocity, reading.linear_acceleration


@pytest.mark.parametrize('heading, expected', [(0.0, (0.0, G, 0.0)), (math.pi / 2, (G, 0.0, 0.0)),
                                               (math.pi, (0.0, -G, 0.0))], ids=['facing +X', 'facing up', 'facing -X'])
def test_at_rest_on_a_vertical_wall_the_accelerometer_reads_g_up_the_wall_in_body_axes(heading, expected):
    """REP 145: the specific force, -gravity at rest: (0, g, 0) in the wall frame, turned into base_link's axes."""
    angular, linear = rest_reading(90.0, heading)
    assert linear == pytest.approx(expected, abs=1e-12) and list(angular) == [0.0, 0.0, 0.0]


@pytest.mark.parametrize('heading', [0.0, 1.0, -2.5])
def test_at_rest_on_the_floor_the_accelerometer_reads_g_along_z_whatever_the_heading(heading):
    _angular, linear = rest_reading(0.0, heading)
    assert linear == pytest.approx((0.0, 0.0, G), abs=1e-12)


@pytest.mark.parametrize('inclination, heading, expected', [(0.0, 0.7, (0.0, 0.0, G)), (90.0, 0.0, (0.0, G, 0.0))],
                         ids=['floor', 'wall facing +X'])
def test_a_simulated_robot_at_rest_reads_the_specific_force_of_its_surface_and_no_turn(inclination, heading, expected):
    """The model's own state at rest (on the floor no in-plane gravity; on the wall facing +X gravity is lateral,
    which non_lateral holds; no torque), sampled by the suite and read back from the message's bytes by rosbags:
    REP 145's +g along z on the floor, along y on the wall."""
    robot = Robot(RobotParameters(sensors={'imu': {}}), World(inclination))
    sim = Simulation(robot, None, ConstraintSelection(False, True, True, True),
                     np.array([0, 0, heading, 0, 0, 0, 0.0]), np.zeros(7))
    suite = SensorSuite(robot.params.sensors, robot, 'base_link')
    for _ in range(10):
        sim.step()
    (topic, data), = suite.encode(sim.outputs())
    msg = bagio.deserialize(data, topic.type)
    acceleration = msg.linear_acceleration
    assert topic is topics.IMU and msg.header.frame_id == 'base_link'
    assert np.abs(sim.qd).max() < 1e-9  # at rest
    assert (acceleration.x, acceleration.y, acceleration.z) == pytest.approx(expected, abs=1e-9)
    assert msg.angular_velocity.z == pytest.approx(0.0, abs=1e-12)
    assert msg.orientation_covariance[0] == -1.0


def test_the_gyroscope_reads_the_turn_rate_and_a_turning_robot_feels_its_centripetal_acceleration():
    """A centre moving on a circle of radius R at speed v, heading along the velocity, on the floor: the specific
    force is (0, v^2 / R, g) in body axes (centripetal acceleration to the left of a left turn)."""
    radius, speed, phase = 0.5, 0.3, 0.4
    rate = speed / radius
    q = np.array([radius * math.cos(phase), radius * math.sin(phase), phase + math.pi / 2, 0, 0, 0, 0])
    qd = np.array([-speed * math.sin(phase), speed * math.cos(phase), rate, 0, 0, 0, 0])
    qdd = np.array([-rate * speed * math.cos(phase), -rate * speed * math.sin(phase), 0, 0, 0, 0, 0])
    reading = Imu(ImuParameters(), gravity(0.0)).measure(q, qd, qdd)
    assert reading.angular_velocity == pytest.approx((0.0, 0.0, rate), abs=1e-15)
    assert reading.linear_acceleration == pytest.approx((0.0, speed ** 2 / radius, G), abs=1e-12)


def errors(params: ImuParameters, samples: int) -> np.ndarray:
    """(samples, 6): gyroscope then accelerometer reading minus the exact one, at rest on a wall."""
    imu, q = Imu(params, gravity(90.0)), np.zeros(7)
    exact = imu.exact(q, AT_REST, AT_REST)
    rows = []
    for _ in range(samples):
        reading = imu.measure(q, AT_REST, AT_REST)
        rows.append(np.concatenate((reading.angular_velocity - exact.angular_velocity,
                                    reading.linear_acceleration - exact.linear_acceleration)))
    return np.array(rows)


def test_the_white_noise_has_the_standard_deviation_of_its_density_at_the_rate():
    """sigma = density sqrt(rate) per sample, zero mean, per axis (20000 samples: the estimate within 3 %)."""
    params = ImuParameters(rate=200.0, accelerometer_noise_density=0.004, gyroscope_noise_density=3e-4, seed=7)
    found = errors(params, 20_000)
    expected = np.array([3e-4] * 3 + [0.004] * 3) * math.sqrt(200.0)
    assert np.std(found, axis=0) == pytest.approx(expected, rel=0.03)
    assert np.all(np.abs(np.mean(found, axis=0)) < 4 * expected / math.sqrt(len(found)))


def test_the_bias_random_walks_with_steps_of_its_walk_over_the_root_of_the_rate():
    """Without white noise the error is the bias: its steps have sigma = walk / sqrt(rate), and its spread after n
    samples grows as sqrt(n) (200 independent walks of 400 samples: the variance within 25 %)."""
    params = ImuParameters(rate=100.0, accelerometer_random_walk=0.02, gyroscope_random_walk=0.001, seed=3)
    found = errors(params, 20_000)
    step = np.array([0.001] * 3 + [0.02] * 3) / math.sqrt(100.0)
    assert np.std(np.diff(found, axis=0), axis=0) == pytest.approx(step, rel=0.03)
    ends = np.array([errors(ImuParameters(rate=100.0, accelerometer_random_walk=0.02, seed=seed), 400)[-1, 3]
                     for seed in range(200)])
    assert np.var(ends) == pytest.approx(400 * step[3] ** 2, rel=0.25)


def test_the_same_seed_gives_the_same_noise_and_another_seed_other_noise():
    noisy = {'accelerometer_noise_density': 0.01, 'gyroscope_random_walk': 0.01}
    first, again = (errors(ImuParameters(seed=5, **noisy), 50) for _ in range(2))
    other = errors(ImuParameters(seed=6, **noisy), 50)
    assert np.array_equal(first, again) and not np.array_equal(first, other)


def test_an_encoder_reads_the_whole_counts_turned_below_the_angle():
    counts = 1024
    step = 2 * math.pi / counts
    angles = np.array([0.0, 0.5 * step, step, 3.7 * step, -0.2 * step, -5.0 * step, 123.456])
    read = quantized(angles, counts)
    whole = read / step
    assert np.allclose(whole, np.round(whole), atol=1e-9, rtol=0)
    assert np.all(read <= angles + 1e-12) and np.all(angles - read < step)
    assert list(np.round(whole)) == [0, 0, 1, 3, -1, -5, math.floor(123.456 / step)]


def test_the_encoders_speed_is_the_count_change_over_the_sample_period_and_restarts_when_time_goes_back():
    counts = 100
    encoders, step = Encoders(EncoderParameters(counts_per_rev=counts)), 2 * math.pi / counts
    _angles, first = encoders.measure(0.0, np.array([0.0, 0.0, 0.0, 0.0]))
    _angles, speed = encoders.measure(0.01, np.array([3.5 * step, -0.5 * step, 0.0, 10 * step]))
    assert list(first) == [0.0] * 4
    assert speed == pytest.approx(np.array([3, -1, 0, 10]) * step / 0.01)
    _angles, after_reset = encoders.measure(0.0, np.zeros(4))
    assert list(after_reset) == [0.0] * 4


def test_the_pressure_sensor_reads_the_chamber_s_absolute_pressure_with_its_bias_and_noise():
    exact = PressureSensor(PressureParameters(bias=-30.0))
    assert exact.measure(10103.0) == ATMOSPHERE - 10103.0 - 30.0
    noisy = PressureSensor(PressureParameters(noise=25.0, seed=2))
    samples = np.array([noisy.measure(5000.0) for _ in range(10_000)])
    assert np.std(samples) == pytest.approx(25.0, rel=0.03)
    assert abs(np.mean(samples) - (ATMOSPHERE - 5000.0)) < 4 * 25.0 / 100


def test_the_suite_samples_each_sensor_at_its_rate_and_its_messages_read_back():
    """One second of a driven climb at 1 kHz: 200 IMU, 100 encoder and 50 pressure samples after the one at t = 0,
    at the multiples of their periods; the encoders' angles on the count grid within a count below the wheels', the
    pressure the chamber's, the covariances the noise's variances."""
    params = RobotParameters(adhesion=VACUUM, sensors={
        'imu': {'accelerometer_noise_density': 0.002, 'gyroscope_noise_density': 1e-4},
        'encoders': {'counts_per_rev': 512}, 'pressure': {'noise': 10.0}})
    robot = Robot(params)
    sim = Simulation(robot, None, ConstraintSelection(False, True, True, True), np.array([0, 0, math.pi / 2, 0, 0, 0, 0.]),
                     np.zeros(7))
    sim.set_motor_torque(1.5, 1.5)
    suite = SensorSuite(params.sensors, robot, 'base_link')
    stamps: dict[str, list[int]] = {topic.name: [] for topic in suite.topics}
    for step in range(1001):  # the state at t = 0, as the dynamics publishes it first, then 1000 steps
        if step:
            sim.step()
        out = sim.outputs()
        for topic, data in suite.encode(out):
            stamps[topic.name].append(codec.leading_stamp_ns(data))
            if topic is topics.JOINT_STATES:
                angles, step = np.array(codec.decode_joint_state(data).position), 2 * math.pi / 512
                assert np.all(out.q[3:] - angles < step) and np.all(angles <= out.q[3:])
            elif topic is topics.CHAMBER_PRESSURE:
                pressure = codec.decode_fluid_pressure(data)
                assert abs(pressure.pressure - (ATMOSPHERE - out.vacuum[0])) < 60.0 and pressure.variance == 100.0
            else:
                imu = codec.decode_imu(data)
                assert imu.linear_acceleration_covariance[::4] == pytest.approx((0.002 ** 2 * 200,) * 3)
                assert imu.angular_velocity_covariance[::4] == pytest.approx((1e-4 ** 2 * 200,) * 3)
    for name, rate in (('imu', 200), ('joint_states', 100), ('chamber_pressure', 50)):
        period = 1_000_000_000 // rate
        assert stamps[name] == [period * k for k in range(rate + 1)], name


@pytest.mark.parametrize('sensors, reason', [
    ({'imu': {'rat': 100}}, "unknown sensors imu key 'rat' (did you mean 'rate'?)"),
    ({'imu': {'rate': 0}}, 'sensors imu rate must be in (0, 100000], got 0'),
    ({'encoders': {'counts_per_rev': 10.5}}, 'sensors encoders counts_per_rev must be a whole number, got 10.5'),
    ({'pressure': {}}, 'sensors pressure measures the vacuum chamber: the robot file has no adhesion block'),
    ({'lidar': {}}, "unknown sensors key 'lidar'"),
])
def test_a_bad_sensors_block_is_refused_naming_the_key(sensors, reason):
    with pytest.raises(ParameterError, match=reason.replace('(', r'\(').replace(')', r'\)').replace('?', r'\?')):
        RobotParameters(sensors=sensors)


def test_a_sensors_block_survives_a_copy_and_a_null_sensor_is_absent():
    params = RobotParameters(sensors={'imu': {'seed': 4}, 'encoders': None})
    assert params.sensors == SensorParameters(imu=ImuParameters(seed=4))
    assert params.replace(body_mass=9.0).sensors == params.sensors
