"""The recorder's run configuration from the simulator (``mcap_recorder``'s
``simulator_node``): its parameters, asked for in the background so that recording never
waits for them, stored in the bag's run configuration when they come."""
from __future__ import annotations

import time
from typing import Any

from rclpy.clock import Clock
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python

from rigid_body_sim.bag.writer import BagWriter


def fetch_simulator_parameters(node: Node, node_name: str, timeout: float, clock: Clock,
                               config: dict[str, Any], writer: BagWriter) -> None:
    """Ask ``node_name`` (relative to ``node``'s namespace unless absolute; '' for none)
    for its parameters, polling for its services on ``clock`` for ``timeout`` s; when they
    come, add them to ``config`` (the run configuration, under the offline record's keys)
    and write it to the bag again. Not found in time: logged, the configuration keeps the
    recorder's own parameters."""
    from rcl_interfaces.srv import GetParameters, ListParameters
    if not node_name:
        return
    base = node_name if node_name.startswith('/') else \
        f'{node.get_namespace().rstrip("/")}/{node_name}'
    config['simulator_node'] = base
    lister = node.create_client(ListParameters, f'{base}/list_parameters')
    getter = node.create_client(GetParameters, f'{base}/get_parameters')
    deadline = time.monotonic() + timeout

    def poll() -> None:
        if lister.service_is_ready() and getter.service_is_ready():
            timer.cancel()
            lister.call_async(ListParameters.Request()).add_done_callback(on_list)
        elif time.monotonic() > deadline:
            timer.cancel()
            node.get_logger().info(f'{base} not found: run configuration holds the '
                                   'recorder parameters only')

    def on_list(future: Any) -> None:
        names = list(future.result().result.names) if future.result() else []
        request = GetParameters.Request(names=names)
        getter.call_async(request).add_done_callback(lambda f: on_get(names, f))

    def on_get(names: list[str], future: Any) -> None:
        if future.result() is None:
            return
        params = {n: parameter_value_to_python(v)
                  for n, v in zip(names, future.result().values)}
        config.update({'integrator': params.get('integrator'),
                       'simulator_parameters': params})
        # the simulator's scene record (engine.specs.SCENE_RECORD), under the offline
        # record's keys; the recorder's own `scene` parameter, if given, names it
        config['scene'] = config['scene'] or params.get('scene.name') or None
        config['scene_sha256'] = params.get('scene.sha256') or None
        writer.add_run_configuration(config)
        node.get_logger().info(f'stored the run configuration of {base} '
                               f'({len(params)} parameters)')

    timer = node.create_timer(0.2, poll, clock=clock)
