"""A parameter storm from a process of its own: set_parameters requests at a steady rate.

    python parameter_storm.py NODE_FQN COUNT RATE_HZ IN_FLIGHT

Sends COUNT ``set_parameters`` requests to NODE_FQN, one every 1/RATE_HZ s, with at most
IN_FLIGHT unanswered (a request that is due while IN_FLIGHT are out waits for an answer: the
service queue never overflows, so every request is answered). Request k sets ``gamma`` to
``1 + k / COUNT`` (every value distinct, in order). Prints ``ready`` once the service is there,
then one JSON line: ``{"sent", "answered", "successful", "values", "seconds"}``, the values being
those of the successful sets, in answer order.
"""
from __future__ import annotations

import json
import sys
import time

import rclpy
from node_harness import ready_to_answer
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor


def gamma_of(k: int, count: int) -> float:
    """Return the gamma of request k of ``count``."""
    return 1.0 + k / count


def main(argv: list[str]) -> int:
    fqn, count, rate, most = argv[0], int(argv[1]), float(argv[2]), int(argv[3])
    rclpy.init()
    node = rclpy.create_node('parameter_storm')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    client = node.create_client(SetParameters, f'{fqn}/set_parameters')
    end = time.monotonic() + 60.0
    while not client.service_is_ready():
        if time.monotonic() > end:
            print('no set_parameters service', file=sys.stderr)
            return 1
        executor.spin_once(timeout_sec=0.01)
    ready_to_answer(node, executor, fqn)
    print('ready', flush=True)
    futures: list[tuple[float, object]] = []
    values: list[float] = []
    answered = successful = sent = 0
    start = time.monotonic()
    period = 1.0 / rate
    while answered < count:
        now = time.monotonic()
        if now - start > 600.0:
            break   # the node stopped answering: the caller sees answered < count
        while sent < count and len(futures) < most and now >= start + sent * period:
            value = gamma_of(sent, count)
            request = SetParameters.Request(parameters=[Parameter(
                name='gamma', value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                   double_value=value))])
            futures.append((value, client.call_async(request)))
            sent += 1
        executor.spin_once(timeout_sec=min(period, 0.001))
        still = []
        for value, future in futures:
            if future.done():  # type: ignore[attr-defined]
                answered += 1
                if future.result().results[0].successful:  # type: ignore[attr-defined]
                    successful += 1
                    values.append(value)
            else:
                still.append((value, future))
        futures = still
    seconds = time.monotonic() - start
    print(json.dumps({'sent': sent, 'answered': answered, 'successful': successful,
                      'values': values, 'seconds': seconds}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
