"""The dynamics loop, free of ROS (``nodes.dynamics`` only wires it to the graph; tested without DDS).

Everything that reaches the loop from outside is a typed event (``events``: a constraint switch, a plan, a torque
command, a reset, a pause, a step or a teleport while paused, a kept snapshot, a parameter change, a recorder's
progress) posted to one thread-safe queue; the loop thread applies the queued events at each step boundary
(``DynamicsLoop.tick``), so no physics runs in a callback and the state sequence depends on the events' order,
not on their timing. What the loop needs of the graph (publishing, the discovery of a recorder, keeper or
controller) goes through a ``graph.Graph``, and its wall-clock waits through an injected clock.

Each tick ends in a ``status.Decision``: a step was taken, or why not (the run state, ``status.RunState``, says
which wait it is), lockstep waits for the controller, or back-pressure waits for a recorder. Its rooms:

* ``start``: what a start waits for (a recorder, a keeper's snapshot, a plan, the controller) and gives up on;
* ``segments``: the simulation of each run segment (the start, a rate change, a reset, a teleport);
* ``waits``: lockstep and back-pressure, the waits on other nodes once running;
* ``commands``: the torque command in force;
* ``pacing``: the wall-clock pace at a real-time factor (and the loop thread's priority);
* ``blocks``: blocks of steps computed ahead on the compiled engine;
* ``snapshots`` and ``resume``: the state kept for a restarted node, and the resume from it;
* ``status``: the run state and the statistics the diagnostics report.

Determinism. The loop does not integrate until it has a constraint set and, while the trajectory task is on, a
plan covering the next step. It never steps past the end of a plan that ends moving (it waits for the next plan
instead), so the state sequence does not depend on pacing, CPU load or message timing: the same configuration
gives the same states at any ``real_time_factor``.
"""

from wallbot_sim.loop.events import (ConstraintSwitch, Event, NewPlan, ParameterChange, Pause, PumpCommand,
                                     RecordProgress, Reset, ResumeSnapshot, Step, Teleport, TorqueCommand)
from wallbot_sim.loop.graph import Graph, Log, PreparedState
from wallbot_sim.loop.loop import DynamicsLoop
from wallbot_sim.loop.pacing import Pacer
from wallbot_sim.loop.status import Decision, RunState, Status, Window

__all__ = ['ConstraintSwitch', 'Decision', 'DynamicsLoop', 'Event', 'Graph', 'Log', 'NewPlan', 'Pacer',
           'ParameterChange', 'Pause', 'PreparedState', 'PumpCommand', 'RecordProgress', 'Reset', 'ResumeSnapshot', 'RunState',
           'Status', 'Step', 'Teleport', 'TorqueCommand', 'Window']
