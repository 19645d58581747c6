"""The interface of the wallbot graph: topic names, types and QoS (``topics``, ``qos``), the constraint
modules and their switches (``constraint_modules``), one encoder and decoder per message (``codec``,
``step_cdr``) and bag-level helpers (``bagio``).

A third-party node can decode ``odom`` with it without the simulator: it imports nothing from
``wallbot_sim``, and only ``qos`` needs rclpy.
"""
