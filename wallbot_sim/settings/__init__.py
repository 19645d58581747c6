"""Every node's parameters, one typed table a node (``table``): what its declarations and descriptors,
its checks, the graph description, the launch file's arguments and the command line's options are
derived from. ROS-free."""

from wallbot_sim.settings.table import Setting, SettingError, SettingsTable, Value, setting, table_of, typed

__all__ = ['Setting', 'SettingError', 'SettingsTable', 'Value', 'setting', 'table_of', 'typed']
