"""One encoder and one decoder per message family of the graph, in plain numbers, without ROS.

Encoders return CDR bytes, written by ``cdr.Writer``: the nodes publish them as serialized messages,
the recorder and ``simulate --bag`` write them, and every ROS tool reads them as the standard types
(test_messages.py checks them against rosbags' and rclpy's serialization). Decoders take the CDR
bytes of a message (what a raw subscription receives, or a bag holds), read them with ``cdr.Reader``
and return plain numbers; malformed bytes are a ValueError naming the family. The families, each in
its own module and registered in ``cdr.FAMILIES``:

================== ===================================== =====================================================
family             topics                                encoder / decoder
================== ===================================== =====================================================
clock              clock, /clock, record_progress        ClockEncoder / decode_clock
odometry           odom, control_odom, ground_truth/odom, OdometryEncoder / decode_odometry
                   reference
joint_state        wheel_states, drive_forces,           JointStateEncoder / decode_joint_state
                   joint_states, joint_commands
imu                imu                                   ImuEncoder / decode_imu
fluid_pressure     chamber_pressure                      FluidPressureEncoder / decode_fluid_pressure
wheel_contact      wheel_contact                         WheelContactEncoder / decode_wheel_contact
wrench             constraint_wrench                     WrenchEncoder / decode_wrench
reference_trajectory reference_trajectory                trajectory / decode_plan
reference_path     reference_path                        path / decode_path
diagnostics        /diagnostics                          diagnostics / decode_diagnostics
faults             faults                                fault_event / decode_fault_event
constraints        constraints                           constraints / decode_constraints
wheel_torque_cmd   wheel_torque_cmd                      wheel_torque_cmd / decode_wheel_torque_cmd
pump_command       pump_command                          pump_command / decode_pump_command
robot_description  robot_description                     robot_description / decode_robot_description
cmd_vel            cmd_vel                               (published by a teleop tool) / decode_cmd_vel
initialpose        initialpose                           (published by RViz) / decode_initial_pose
state_snapshot     state_snapshot, resume_state          ``snapshot.encode_snapshot`` / ``snapshot.decode_snapshot``
markers, tf        markers, /tf                          ``view_cdr.marker_array``, ``view_cdr.tf_message`` /
                                                         (read only by RViz and Foxglove)
================== ===================================== =====================================================

The per-step families' encoders are byte templates (a few ``struct.pack_into`` per message), which
``step_cdr.StepEncoder`` composes for the dynamics' 1 kHz steps. Each writes its messages into one buffer
of its own before copying them out: an encoder serves one thread.

Conventions (REP 103/105): poses in frame ``wall`` (X right, Y up, Z out of the wall), the robot
frame ``base_link`` at the geometric centre; odometry twists are in the child frame, so
twist.linear = (v_long, v_lat) and twist.angular.z = the turning rate. Every stamp is
simulation time.
"""

from wallbot_msgs_py.cdr import leading_stamp_ns, to_nanoseconds
from wallbot_msgs_py.codec.clock import ClockEncoder, decode_clock
from wallbot_msgs_py.codec.commands import (decode_cmd_vel, decode_initial_pose, decode_pump_command,
                                            decode_robot_description, decode_wheel_torque_cmd, pump_command,
                                            robot_description, wheel_torque_cmd)
from wallbot_msgs_py.codec.joints import (CONTACT_NAMES, JOINT_FIELDS, JointArrays, JointStateEncoder, WheelContact,
                                          WheelContactEncoder, Wrench, WrenchEncoder, decode_joint_state,
                                          decode_wheel_contact, decode_wrench)
from wallbot_msgs_py.codec.odometry import (NO_VARIANCE, OdometryEncoder, OdometryMessage, PlanarState,
                                            decode_odometry, yaw_of, yaw_quaternion)
from wallbot_msgs_py.codec.plan import PathMessage, PlanSamples, decode_path, decode_plan, path, trajectory
from wallbot_msgs_py.codec.sensors import (FluidPressureEncoder, ImuEncoder, ImuMessage, PressureMessage,
                                           decode_fluid_pressure, decode_imu)
from wallbot_msgs_py.codec.status import (CONSTRAINTS_STATUS_NAME, GAINS, HARDWARE_ID, LEVELS, ConstraintSwitches,
                                          Diagnostics, FaultEvent, Status, constraints, decode_constraints,
                                          decode_diagnostics, decode_fault_event, diagnostics, fault_event,
                                          simulation_status, simulation_status_name)

__all__ = [
    'CONSTRAINTS_STATUS_NAME', 'CONTACT_NAMES', 'GAINS', 'JOINT_FIELDS', 'HARDWARE_ID', 'LEVELS', 'NO_VARIANCE',
    'ClockEncoder', 'FluidPressureEncoder', 'ImuEncoder', 'ImuMessage', 'PressureMessage', 'decode_fluid_pressure',
    'decode_imu', 'decode_pump_command', 'pump_command',
    'ConstraintSwitches', 'Diagnostics', 'FaultEvent', 'JointArrays', 'JointStateEncoder', 'OdometryEncoder', 'OdometryMessage',
    'PathMessage', 'PlanSamples', 'PlanarState', 'Status', 'WheelContact', 'WheelContactEncoder', 'Wrench',
    'WrenchEncoder', 'constraints', 'decode_clock', 'decode_cmd_vel', 'decode_constraints',
    'decode_diagnostics', 'decode_fault_event', 'decode_initial_pose', 'decode_joint_state', 'decode_odometry', 'decode_path',
    'decode_plan', 'decode_robot_description', 'decode_wheel_contact', 'decode_wheel_torque_cmd', 'decode_wrench',
    'diagnostics', 'fault_event', 'leading_stamp_ns', 'path', 'robot_description', 'simulation_status',
    'simulation_status_name', 'to_nanoseconds', 'trajectory', 'wheel_torque_cmd', 'yaw_of', 'yaw_quaternion',
]
