"""A controller test's outcome as JUnit XML, the report format CI systems read (Jenkins, GitLab, GitHub Actions).

One ``testsuite`` named after the spec, with its settings as ``properties``; one ``testcase`` for the run itself
(``run``: it covered its duration, the controller answering every state) and one per expectation, named after it.
A failing testcase holds a ``failure`` whose message is its one-line verdict; one that could not be judged is
``skipped``; every testcase's ``system-out`` gives the measured value, the limit and the time of the worst instant.
"""

from __future__ import annotations

import math
import socket
import xml.etree.ElementTree as ET
from datetime import datetime, timezone
from pathlib import Path

from wallbot_sim.testing.expectations import Verdict
from wallbot_sim.testing.outcome import Outcome


def junit_xml(outcome: Outcome) -> ET.ElementTree:
    """The JUnit document of ``outcome``."""
    spec = outcome.spec
    verdicts = (outcome.run_verdict, *outcome.verdicts)
    counts = {'tests': len(verdicts), 'failures': sum(v.passed is False for v in verdicts), 'errors': 0,
              'skipped': sum(v.passed is None for v in verdicts)}
    root = ET.Element('testsuites', {key: str(value) for key, value in counts.items() if key != 'skipped'})
    suite = ET.SubElement(root, 'testsuite', {
        'name': spec.name, **{key: str(value) for key, value in counts.items()},
        'time': f'{outcome.wall_time:.3f}', 'timestamp': datetime.now(timezone.utc).strftime('%Y-%m-%dT%H:%M:%S'),
        'hostname': socket.gethostname()})
    properties = ET.SubElement(suite, 'properties')
    for name, value in (('scenario', spec.scenario), ('contact', spec.contact), ('duration', f'{outcome.duration:g}'),
                        ('drive', spec.drive), ('control_rate', str(spec.rate)),
                        ('controller', ' '.join(spec.controller)), ('bag', str(outcome.bag)),
                        *((f'fault at {event.stamp_ns * 1e-9:.3f} s', f'{", ".join(event.changed)} '
                           f'({event.cause})') for event in outcome.faults)):
        ET.SubElement(properties, 'property', {'name': name, 'value': value})
    for verdict in verdicts:
        case = ET.SubElement(suite, 'testcase', {'classname': f'wallbot_sim.{_identifier(spec.name)}',
                                                 'name': verdict.name, 'time': '0'})
        if verdict.passed is False:
            ET.SubElement(case, 'failure', {'type': 'ExpectationFailed', 'message': verdict.detail}).text = \
                measured(verdict)
        elif verdict.passed is None:
            ET.SubElement(case, 'skipped', {'message': verdict.detail})
        ET.SubElement(case, 'system-out').text = measured(verdict)
    ET.indent(root)
    return ET.ElementTree(root)


def measured(verdict: Verdict) -> str:
    """'measured M UNIT, limit L UNIT, worst at t = T s' and the verdict's detail."""
    unit = f' {verdict.unit}' if verdict.unit else ''
    worst = f', worst at t = {verdict.worst_t:.3f} s' if math.isfinite(verdict.worst_t) else ''
    return f'measured {verdict.measured:.6g}{unit}, limit {verdict.limit:g}{unit}{worst}\n{verdict.detail}\n'


def write_junit(outcome: Outcome, path: Path) -> Path:
    """Write the JUnit document of ``outcome`` to ``path`` (its folder created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    junit_xml(outcome).write(path, encoding='utf-8', xml_declaration=True)
    return path


def _identifier(name: str) -> str:
    return ''.join(character if character.isalnum() else '_' for character in name) or 'test'
