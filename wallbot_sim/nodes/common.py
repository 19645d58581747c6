"""Small helpers shared by the nodes: parameter declaration with descriptors, a clean main()."""

from __future__ import annotations

import math
import sys
from typing import Callable, Iterable

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher

from wallbot_sim.model import ModelError


def declare(node: Node, name: str, default, description: str, *, low: float | None = None,
            high: float | None = None, read_only: bool = False):
    """Declare ``name`` with a descriptor (description, range if given); return its value.

    Ranges are closed [low, high]; rclpy refuses out-of-range sets with a reason. Finiteness
    and strict bounds are checked by each node's parameter callback (see ``check_number``).
    """
    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    if low is not None or high is not None:
        if isinstance(default, bool) or not isinstance(default, (int, float)):
            raise TypeError(f'range on non-numeric parameter {name}')
        if isinstance(default, int):
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high),
                                                                  step=0.0)]
    return node.declare_parameter(name, default, descriptor).value


def check_number(name: str, value, *, minimum: float | None = None, exclusive: bool = False) -> str | None:
    """Reason why ``value`` is not an acceptable number for ``name``, or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return f'{name} must be a finite number, got {value!r}'
    if minimum is not None and (value <= minimum if exclusive else value < minimum):
        return f'{name} must be {">" if exclusive else ">="} {minimum:g}, got {value!r}'
    return None


def parameter_result(reasons: Iterable[str | None]) -> SetParametersResult:
    """Successful unless a reason is given; the reasons are what ``ros2 param set`` prints."""
    problems = [reason for reason in reasons if reason]
    return SetParametersResult(successful=not problems, reason='; '.join(problems))


def run(factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """Create the node and spin it until Ctrl-C or SIGTERM; exit 0 without a traceback.

    A configuration error while building the node (e.g. a bad robot file) is logged on one
    line and gives exit status 1.
    """
    rclpy.init(args=args)  # installs SIGINT and SIGTERM handlers that shut the context down
    node = None
    status = 0
    try:
        node = factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ModelError, ValueError, OSError) as error:
        print(f'error: {error}', file=sys.stderr)
        status = 1
    except Exception:  # noqa: BLE001
        # A signal that shuts the context down while the executor builds its wait set makes rclpy
        # raise RCLError ('the given context is not valid') instead of ExternalShutdownException.
        if node is None or node.context.ok():
            raise
    finally:
        if node is not None:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    return status


UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
"""The node name rmw reports for an endpoint whose node it has not yet discovered."""


def heard_by_every(node: Node, publisher: Publisher, senders_topic: str) -> bool:
    """Whether some node publishes on ``senders_topic``, each such node subscribes ``publisher``'s
    topic, and every discovered subscription of that topic is matched to ``publisher`` (so a
    message published now reaches all of them).

    Endpoints of nodes not yet identified all carry UNKNOWN_NODE, which would make a sender look
    like it subscribes when another unidentified node does: not ready until every sender is known.
    """
    senders = {(i.node_namespace, i.node_name) for i in node.get_publishers_info_by_topic(senders_topic)}
    listeners = node.get_subscriptions_info_by_topic(publisher.topic_name)
    return (bool(senders) and all(name != UNKNOWN_NODE for _namespace, name in senders)
            and senders <= {(i.node_namespace, i.node_name) for i in listeners}
            and publisher.get_subscription_count() >= len(listeners))


def param_dict(parameters: list[Parameter], known: Iterable[str] | None = None) -> dict[str, object]:
    """{name: value} of a parameter callback's list; only the names in ``known`` when given."""
    names = None if known is None else set(known)
    return {p.name: p.value for p in parameters if names is None or p.name in names}
