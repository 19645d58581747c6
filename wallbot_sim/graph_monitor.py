"""What a launcher sees of the graph it started (``wallbot-sim run``, ``wallbot-sim test``, the pytest fixture): how far
the recorder got, the dynamics' diagnostics and the state it last published, the trajectory node's reference poses;
and the dynamics' parameters it sets. A node of its own, in the run's domain and the robot's namespace."""

from __future__ import annotations

import math
import os
import time
from contextlib import contextmanager
from typing import TYPE_CHECKING, Iterator, Mapping

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.snapshot import DynamicsSnapshot, decode_snapshot
from wallbot_sim import messages
from wallbot_sim.heartbeat import NODE_HEARTBEAT, PROFILES_ENV, PROFILES_ENVS, profile_path

if TYPE_CHECKING:
    from rclpy.event_handler import QoSRequestedIncompatibleQoSInfo

PARAMETER_TIMEOUT = 10.0
"""Wall seconds a parameter set waits for the dynamics' answer."""
REPLY_WAIT = 2.0
"""Wall seconds to wait for the reply to one parameter request before sending it again."""


def participant_environment() -> dict[str, str]:
    """The environment the monitor joins DDS with: localhost discovery, and (unless the user set a profile file) the
    nodes' Fast DDS profile, so that it keeps announcing itself while the nodes join (``heartbeat``): a node joining
    after it would otherwise often find it only at its periodic announcement, 3 s later."""
    values = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    if not any(os.environ.get(name) for name in PROFILES_ENVS):
        values[PROFILES_ENV] = str(profile_path(NODE_HEARTBEAT))
    return values


@contextmanager
def temporary_environment(values: Mapping[str, str]) -> Iterator[None]:
    """``values`` in os.environ while the block runs, the previous values (or their absence) restored after."""
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


class ParameterRefused(RuntimeError):
    """The dynamics refused a parameter set, or did not answer it (the one-line reason)."""


class Monitor:
    """The launcher's own view of the graph: how far the recorder got, the dynamics' diagnostics and latest state.

    ``domain_id``: the run's ROS_DOMAIN_ID, for a launcher whose environment names another (the pytest fixture; a
    ``wallbot-sim`` verb exports the run's domain instead); discovery stays on this machine either way."""

    def __init__(self, namespace: str = topics.NAMESPACE, domain_id: int | None = None) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import Odometry, Path
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import Float64MultiArray

        from rclpy.event_handler import SubscriptionEventCallbacks

        from wallbot_msgs_py.qos import offered_qos_profile, qos_profile
        from wallbot_sim.nodes.common import events_executor
        self._rclpy = rclpy
        self.context = rclpy.Context()
        # read as the context and the process's first participant are made (the profile: once per process); the
        # launcher's children, started with an environment of their own, choose their own
        with temporary_environment(participant_environment()):
            rclpy.init(context=self.context, domain_id=domain_id,
                       signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
            self.node = rclpy.create_node('run_monitor', namespace=namespace, context=self.context)
        self.executor = events_executor(self.context)  # a callback per message, no wait set per wake-up
        self.executor.add_node(self.node)
        self.recorded = -math.inf
        """Simulation time up to which the recorder has written the run: its newest record_progress (which
        goes back with the run at a ``~/reset`` of the dynamics)."""
        self.diagnostics: dict[str, str] = {}
        """The values of the newest status of the dynamics in ``namespace``."""
        self.snapshot: DynamicsSnapshot | None = None
        """The newest state the dynamics published as a snapshot (at its events, and where a stop holds it)."""
        self.reference_time = -math.inf
        self.planned = False
        """Whether the trajectory node's path (latched, published with each plan) has arrived: it plans once a
        recorder hears its reference, so its poses from then on are recorded."""
        self.progress_topic = topics.RECORD_PROGRESS.resolve(namespace)
        self._parameters = None
        self.node.create_subscription(Clock, topics.RECORD_PROGRESS.name, self._on_progress,
                                      qos_profile(topics.RECORD_PROGRESS), raw=True)
        self.unheard_status_publishers = 0
        """Publishers on /diagnostics this monitor does not match: volatile ones, another program's (the dynamics offers
        transient-local), whose statuses are not its robot's; counted here, not warned about on the terminal."""
        # transient-local, as the dynamics offers it: a status it published before this reader matched (the stop's,
        # which the end of a run waits for) arrives with the match, not with the next one a second later
        self.node.create_subscription(
            DiagnosticArray, topics.DIAGNOSTICS.name, self._on_diagnostics, offered_qos_profile(topics.DIAGNOSTICS),
            raw=True, event_callbacks=SubscriptionEventCallbacks(incompatible_qos=self._on_unheard_status_publisher))
        # only the stamp is read (100 poses per simulated second)
        self.reference_subscription = self.node.create_subscription(
            Odometry, topics.REFERENCE.name, self._on_reference, qos_profile(topics.REFERENCE), raw=True)
        self.node.create_subscription(Path, topics.REFERENCE_PATH.name, self._on_path,
                                      qos_profile(topics.REFERENCE_PATH), raw=True)
        self.node.create_subscription(Float64MultiArray, topics.STATE_SNAPSHOT.name, self._on_snapshot,
                                      qos_profile(topics.STATE_SNAPSHOT), raw=True)

    def _on_progress(self, data: bytes) -> None:
        self.recorded = codec.decode_clock(data) * 1e-9

    def _on_reference(self, data: bytes) -> None:
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is not None:
            self.reference_time = stamp_ns * 1e-9

    def _on_path(self, data: bytes) -> None:
        self.planned = True

    def _on_snapshot(self, data: bytes) -> None:
        try:
            self.snapshot = decode_snapshot(data)
        except ValueError:
            return

    def _on_unheard_status_publisher(self, event: QoSRequestedIncompatibleQoSInfo) -> None:
        self.unheard_status_publishers = event.total_count

    def _on_diagnostics(self, data: bytes) -> None:
        try:  # every robot of the domain publishes on /diagnostics: its own dynamics' status only
            status = codec.simulation_status(codec.decode_diagnostics(data).statuses, self.node.get_namespace())
        except ValueError:
            return
        if status is not None:
            self.diagnostics = status.value_map()

    @property
    def status(self) -> str:
        """The dynamics' newest status ('running', 'stopped at ...', 'gave up: ...'), '' before its first."""
        return self.diagnostics.get('status', '')

    def dynamics_stopped(self) -> bool:
        """Whether the dynamics' latest diagnostics say it has stopped (so they cover every step)."""
        return self.status.startswith('stopped')

    def kernel_loading(self) -> bool:
        """Whether the dynamics' latest diagnostics say it is loading its compiled kernel."""
        return self.status == messages.LOADING_KERNEL

    def reference_planned(self) -> bool:
        """Whether the trajectory node has planned for a recorder (its latched path has arrived) and its reference
        reaches the monitor (the poses sent before do not)."""
        return self.planned and self.reference_subscription.get_publisher_count() > 0

    def reference_reached(self, duration: float) -> bool:
        """Whether nothing more of the reference is to come here for a run of ``duration``: its last pose has
        arrived, or none has. The trajectory node's writer can match this reader (its side of discovery, which the
        monitor cannot see) only after a short run's poses went out (seen under load: 1 run in ~15 of 1 s), and
        those the recorder, heard before the first pose, has taken."""
        last_pose = duration - 1.0 / messages.PUBLISH_RATE_HZ - 1e-9
        return self.reference_time == -math.inf or self.reference_time >= last_pose

    def spin(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

    def recorder_ready(self) -> bool:
        return self.node.count_publishers(self.progress_topic) > 0

    def set_dynamics_parameters(self, values: Mapping[str, object]) -> None:
        """Set parameters of the dynamics as ``ros2 param set`` does (they apply at its next step boundary);
        ParameterRefused with the dynamics' reason if it refuses one, or if it does not answer."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        if self._parameters is None:
            self._parameters = self.node.create_client(SetParameters, f'{topics.NODE_DYNAMICS}/set_parameters')
        if not self._parameters.wait_for_service(PARAMETER_TIMEOUT):
            raise ParameterRefused(f'the dynamics offers no parameter service within {PARAMETER_TIMEOUT:g} s')
        request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()
                                                    for name, value in values.items()])
        # a service is available once its request reader matches; the reply is lost while the server has not yet
        # matched this client's reply reader (seen under load: no answer ever), so an unanswered request is sent
        # again: parameters are values, setting them twice changes nothing
        deadline = time.monotonic() + PARAMETER_TIMEOUT
        future = self._parameters.call_async(request)
        self.executor.spin_until_future_complete(future, timeout_sec=REPLY_WAIT)
        while not future.done() and time.monotonic() < deadline:
            self._parameters.remove_pending_request(future)
            future = self._parameters.call_async(request)
            self.executor.spin_until_future_complete(future, timeout_sec=REPLY_WAIT)
        if not future.done():
            raise ParameterRefused(f'the dynamics did not answer a parameter set within {PARAMETER_TIMEOUT:g} s')
        refused = [result.reason for result in future.result().results if not result.successful]
        if refused:
            raise ParameterRefused('; '.join(refused))

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
