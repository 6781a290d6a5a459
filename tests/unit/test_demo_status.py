"""The demo reads the predictor's counts from its newest forecast status on /diagnostics."""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from vessel_bringup.demo import predictor_status


def report(name: str, published: int) -> DiagnosticArray:
    return DiagnosticArray(status=[DiagnosticStatus(name=name, values=[
        KeyValue(key='forecasts_published', value=str(published))])])


def test_the_newest_forecast_status_counts_not_another_nodes_report():
    reports = [report('/vessel/predictor: forecast', 245),
               report('/vessel/predictor: forecast', 246),
               report('/vessel/simulator: simulation', 999)]   # newest, another node's
    assert predictor_status(reports) == {'forecasts_published': '246'}
    assert predictor_status(reports[:1]) == {'forecasts_published': '245'}
    assert predictor_status([report('/vessel/simulator: simulation', 1)]) == {}
    assert predictor_status([]) == {}
