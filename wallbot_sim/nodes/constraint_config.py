"""constraint_config_node: the constraint switches as parameters, published on ``constraints``.

``ros2 param set /wallbot/constraint_config nonslip true`` switches the dynamics at its next
step boundary (the dynamics node projects the velocities onto newly added constraints).
"""

from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.node import Node

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim import messages
from wallbot_sim.model import BaumgarteGains, ModelError
from wallbot_sim.model.numbers import POSITIVE
from wallbot_sim.nodes.common import declare, param_dict, parameter_result, run

def _default_gains() -> BaumgarteGains:
    """The installed robot file's Baumgarte gains (the model defaults if it cannot be read)."""
    try:
        from wallbot_sim.config import load_robot_parameters
        params = load_robot_parameters()
        return BaumgarteGains(params.baumgarte_alpha, params.baumgarte_beta)
    except (ModelError, OSError):
        return BaumgarteGains()


class ConstraintConfigNode(Node):
    """Owns the switches; publishes the active set (transient-local) at start and on every change."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_CONSTRAINT_CONFIG, namespace=topics.NAMESPACE, **kwargs)
        self.switches = {switch.parameter: bool(declare(self, switch.parameter, switch.default, switch.description))
                         for switch in topics.CONSTRAINT_MODULES.values()}
        gains = _default_gains()
        self.gains = {
            'baumgarte_alpha': declare(self, 'baumgarte_alpha', float(gains.alpha),
                                       'Baumgarte gain alpha (1/s, > 0)', low=0.0, high=1e4),
            'baumgarte_beta': declare(self, 'baumgarte_beta', float(gains.beta),
                                      'Baumgarte gain beta (1/s, > 0)', low=0.0, high=1e4),
        }
        reason = self._check(self.gains)
        if reason:
            raise ValueError(reason)
        self.publisher = self.create_publisher(DiagnosticStatus, topics.CONSTRAINTS.name,
                                               qos_profile(topics.CONSTRAINTS))
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.publish()

    @staticmethod
    def _check(values: dict) -> str | None:
        reasons = [POSITIVE.reason(name, values[name]) for name in codec.GAINS if name in values]
        return '; '.join(r for r in reasons if r) or None

    def _on_set(self, parameters):
        values = param_dict(parameters)
        return parameter_result([self._check(values)])

    def _after_set(self, parameters) -> None:
        changed = False
        for name, value in param_dict(parameters).items():
            if name in self.switches:
                self.switches[name], changed = bool(value), True
            elif name in self.gains:
                self.gains[name], changed = float(value), True
        if changed:
            self.publish()

    def publish(self) -> None:
        """Publish the current set and log it."""
        self.publisher.publish(messages.constraints_message(
            self.switches, BaumgarteGains(self.gains['baumgarte_alpha'], self.gains['baumgarte_beta'])))
        label = messages.selection_from_switches(self.switches).label()
        self.get_logger().info(f'constraints: {label} (alpha {self.gains["baumgarte_alpha"]:g}, '
                               f'beta {self.gains["baumgarte_beta"]:g})')


def main(args: list[str] | None = None) -> None:
    sys.exit(run(ConstraintConfigNode, args))


if __name__ == '__main__':
    main()
