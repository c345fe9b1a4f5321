"""The tests' service helper (ros_helpers.call_service): a response lost on the way (a
server's response writer not yet matched with the client's reader, under load) is asked
for again where the caller allows it, and fails the test with the service's name where
it does not."""
import pytest

from ros_helpers import call_service

pytestmark = pytest.mark.fast


class _Client:
    """A client whose first request is never answered (its response lost), the second at
    once."""
    srv_name = '/lossy/service'

    def __init__(self):
        self.requests = []

    def service_is_ready(self):
        return True

    def call_async(self, request):
        from rclpy.task import Future
        self.requests.append(request)
        future = Future()
        if len(self.requests) == 2:
            future.set_result(f'answer to {request}')
        return future


def test_a_lost_response_is_asked_for_again(rclpy_node):
    client, sends = _Client(), []
    assert call_service(rclpy_node, client, 'pause', timeout=20.0, resend=0.3,
                        sends=sends) == 'answer to pause'
    assert client.requests == ['pause', 'pause'] and sends == [2]


def test_without_resend_a_lost_response_fails_with_the_service_name(rclpy_node):
    client = _Client()
    with pytest.raises(AssertionError, match='/lossy/service'):
        call_service(rclpy_node, client, 'pause', timeout=0.5)
    assert client.requests == ['pause']
