"""tracking_controller_node (``/wallbot/controller``): an example closed-loop controller.

Thin ROS shell around ``wallbot_sim.control.SampledController``, which runs a
``TrackingController`` (model-based feed-forward from the Udwadia-Phohomsiri inverse dynamics of
its own robot copy, plus PD and integral feedback; see those modules and docs/controller.md) at
its control rate; ``wallbot-sim simulate --controller`` runs the same loop headless. Replace it
with your own controller by
speaking the same three topics:

* subscribes ``odom`` (nav_msgs/Odometry, pose in ``wall``, twist in ``base_link``) and
  ``reference_trajectory`` (the trajectory node's plan, transient-local);
* publishes ``wheel_torque_cmd`` (std_msgs/Float64MultiArray ``[tau_L, tau_R]``, N m).

Timing is simulation time taken from the odometry stamps, not from a ROS timer: the
controller acts on the first ``odom`` stamped at or after each multiple of 1 / ``rate_hz``
(every 40th message of the 1 kHz dynamics at 25 Hz). So its control instants are the same
at any real-time factor or CPU load, and no ``/clock`` subscription is needed. A stamp that
goes back into the first control period (the dynamics' ``~/reset``, or a dynamics started afresh)
restarts the controller (integral cleared); one that goes back less is a dynamics resumed after a
kill, publishing again states this node saw but the recorder had not: the controller carries on,
acting again from the next control instant at or after it.

The wheel spin rates are not read: the driven robot's wheels roll on the wall (nonslip),
so the controller takes their rolling values from the odometry twist.

A command is published once the dynamics will hear it (it subscribes wheel_torque_cmd and this
publisher is matched to it): until then the newest one is held, since a lost answer would leave a
lockstep dynamics waiting for it.

Safety: commands are clamped to ``max_wheel_torque`` (the dynamics rejects larger ones) and
a command that is not finite is never published (the error is logged; the dynamics then
falls back to zero torque after its ``command_timeout``).
"""

from __future__ import annotations


import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control import ControllerGains, TrackingController
from wallbot_sim.control.sampling import Rewind, SampledController, controller_robot
from wallbot_sim.model import ModelError, Robot, SampledReference
from wallbot_sim.model.simulation import NUMBA
from wallbot_sim.model.trajectories import STAMP_RESOLUTION
from wallbot_sim.nodes.common import ROBOT_CLOCK_ARGS, HeldCommands, exit_process, run, subscribe_odom_when_recorded
from wallbot_sim.nodes.parameters import declare_typed, param_dict, parameter_result
from wallbot_sim.settings.controller import CONTROLLER, GAIN_NAMES, ControllerSettings
from wallbot_sim.settings.table import changed

NODE_NAME = 'controller'
THROTTLE = 1.0
"""Seconds between repeated log lines of one kind."""
KEPT_PLANS = 3
"""Plans kept: the newest one that has started is used, so a plan that starts a little after
the state being handled (the trajectory node replans from its own view of the clock) never
leaves the controller without a reference."""


class Plans:
    """The received plans as one reference: the newest plan that has started by t."""

    def __init__(self) -> None:
        self.plans: list[tuple[float, SampledReference]] = []

    def add(self, start: float, reference: SampledReference) -> None:
        self.plans = [p for p in self.plans if p[0] < start - STAMP_RESOLUTION][-(KEPT_PLANS - 1):] + [(start, reference)]

    def clear(self) -> None:
        self.plans = []

    def __bool__(self) -> bool:
        return bool(self.plans)

    def sample(self, t: float):
        for start, reference in reversed(self.plans):
            if start <= t + STAMP_RESOLUTION:
                return reference.sample(t)
        return self.plans[0][1].sample(t)


class ControllerNode(Node):
    """odom + reference_trajectory -> wheel_torque_cmd at rate_hz of simulation time."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        self.settings: ControllerSettings = declare_typed(self, ControllerSettings, CONTROLLER)
        self.file_params = load_robot_parameters(self.settings.robot_file or None)
        self.plans = Plans()
        self.controller = TrackingController(self._robot(self.settings.mass_scale), None, self._gains(self.settings),
                                             self.settings.engine)
        if self.settings.engine == NUMBA:
            # before the first state can come: a first call would compile or load the kernel, seconds to a minute
            from wallbot_sim.model.compiled import compile_inverse_dynamics
            compile_inverse_dynamics()
        self.controller.reference = self.plans
        self.loop = SampledController(self.controller, self.settings.rate_hz, self.settings.max_wheel_torque)
        self.pending: bytes | None = None
        self.commands = 0
        self.clamped = 0

        self.command_pub = self.create_publisher(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name,
                                                 qos_profile(topics.WHEEL_TORQUE_CMD))
        self.create_subscription(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name, self._on_plan,
                                 qos_profile(topics.REFERENCE_TRAJECTORY), raw=True)
        subscribe_odom_when_recorded(self, self.settings.wait_for_recorder, self.command_pub, self._subscribe_odom)
        self.delivery = HeldCommands(self, self.command_pub, topics.ODOM.name)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.get_logger().info(
            f'tracking controller at {self.settings.rate_hz} Hz of simulation time, '
            f'{self.settings.engine} engine, mass_scale {self.settings.mass_scale:g} '
            f'(body_mass {self.controller.robot.params.body_mass:g} kg), '
            + ', '.join(f'{name} {getattr(self.settings, name):g}' for name in GAIN_NAMES))

    # --- model ---------------------------------------------------------------------------------
    def _robot(self, mass_scale: float) -> Robot:
        return controller_robot(self.file_params, mass_scale)

    @staticmethod
    def _gains(settings: ControllerSettings) -> ControllerGains:
        return ControllerGains(**{name: getattr(settings, name) for name in GAIN_NAMES})

    # --- start-up -----------------------------------------------------------------------------
    def _subscribe_odom(self) -> None:
        # raw: of the 1 kHz odometry only the messages acted on are decoded (the stamp is read
        # from the CDR bytes), which keeps the controller's CPU share low on a busy machine
        self.create_subscription(Odometry, topics.ODOM.name, self._on_odom, qos_profile(topics.ODOM), raw=True)

    # --- callbacks -----------------------------------------------------------------------------
    def _on_plan(self, data: bytes) -> None:
        try:
            plan = messages.plan_from_cdr(data)
            reference = messages.sampled_reference(plan)  # as the dynamics node interpolates it
        except (ValueError, ModelError) as error:
            self.get_logger().error(f'ignoring reference_trajectory: {error}')
            return
        self.plans.add(messages.plan_sample_times(plan)[0], reference)
        if self.pending is not None:  # a state that came before the first plan
            msg, self.pending = self.pending, None
            self._on_odom(msg)

    def _on_odom(self, data: bytes) -> None:
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is None:
            self.get_logger().error('ignoring a malformed odom message', throttle_duration_sec=THROTTLE)
            return
        rewind = self.loop.observe(stamp_ns)
        if rewind is Rewind.RESTART:
            self.get_logger().info(f'simulation time went back to {stamp_ns * 1e-9:.3f} s: controller restarted')
        elif rewind is Rewind.RESUME:
            self.get_logger().info(f'simulation time went back to {stamp_ns * 1e-9:.3f} s (a resumed dynamics): '
                                   'carrying on')
        if not self.loop.due(stamp_ns):
            return
        if not self.plans:
            self.pending = data
            self.get_logger().info('waiting for reference_trajectory', throttle_duration_sec=THROTTLE)
            return
        self._control(data)

    def _control(self, data: bytes) -> None:
        try:
            command = self.loop.command(codec.decode_odometry(data).planar_state())
        except (ValueError, ModelError, np.linalg.LinAlgError) as error:
            self.get_logger().error(f'no command at t = {codec.leading_stamp_ns(data) * 1e-9:.3f} s: {error}',
                                    throttle_duration_sec=THROTTLE)
            return
        if command.clamped:
            self.clamped += 1
            self.get_logger().warning(f'torques {command.requested[0]:.3f}, {command.requested[1]:.3f} N m clamped to '
                                      f'+-{self.loop.max_wheel_torque:g} N m', throttle_duration_sec=THROTTLE)
        self.commands += 1
        if not self.delivery.send(codec.wheel_torque_cmd(command.tau_left, command.tau_right)):
            self.get_logger().info('holding the command until the dynamics hears wheel_torque_cmd',
                                   throttle_duration_sec=THROTTLE)

    # --- parameters ----------------------------------------------------------------------------
    def _on_set(self, parameters):
        changes = param_dict(parameters)
        reasons = CONTROLLER.reasons(changes)
        if not reasons and 'mass_scale' in changes:
            try:
                self._robot(changes['mass_scale'])
            except ModelError as error:
                reasons.append(str(error))
        return parameter_result(reasons)

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, CONTROLLER.names)
        if not changes:
            return
        self.settings = changed(self.settings, changes)
        if set(changes) & set(GAIN_NAMES):
            self.controller.gains = self._gains(self.settings)
        if 'mass_scale' in changes:
            self.controller.robot = self._robot(self.settings.mass_scale)
        if 'max_wheel_torque' in changes:
            self.loop.max_wheel_torque = self.settings.max_wheel_torque
        if 'rate_hz' in changes:
            self.loop.set_rate(self.settings.rate_hz)
        self.get_logger().info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))

def main(args: list[str] | None = None) -> None:
    exit_process(run(ControllerNode, args, events=True))


if __name__ == '__main__':
    main()
