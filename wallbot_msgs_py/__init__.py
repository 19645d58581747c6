"""The interface layer of wallbot_sim: topics, QoS, messages and model<->message conversions.

Shared by the nodes and the tools; holds no node code. ``topics`` needs no ROS install.
"""
