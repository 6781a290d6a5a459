"""The predictor's rate-limited log lines: a warning and then an error do not kill it."""

import rclpy.logging

from hybrid_predictor.node import PredictorNode


class LoggingOnly:
    """What ``PredictorNode._say`` uses of a node: one logger, kept, as a node's is."""

    def __init__(self):
        self._said = {}
        self.logger = rclpy.logging.get_logger('test_predictor_logging')

    def get_logger(self):
        return self.logger


def test_a_warning_then_an_error_are_both_said():
    # rclpy keys each logging call by its code position and raises ValueError when one
    # position logs at two severities: the predictor died of it ("forecast withheld"
    # said as an error after a rejected input had been said as a warning).
    node = LoggingOnly()
    PredictorNode._say(node, 'rejected', 'rejected input: a stamp ahead of the clock')
    PredictorNode._say(node, 'withheld', 'forecast withheld: the window is incomplete',
                       error=True)
    PredictorNode._say(node, 'plan', 'ignoring a stale plan')
    assert set(node._said) == {'rejected', 'withheld', 'plan'}
