"""The recorder writes each message once when several of its readers take a topic: a copy that a
second reader delivers is dropped, equal messages published on purpose are all kept."""
from itasc_bringup.recording.duplicates import Duplicates


def written(arrivals: list[tuple[bytes, int]], *, window: int = 100) -> list[bytes]:
    duplicates = Duplicates(window=window)
    return [data for data, reader in arrivals if duplicates.new(data, reader=reader)]


def test_a_message_both_readers_take_is_written_once_whichever_comes_first():
    assert written([(b'a', 0), (b'a', 1), (b'b', 1), (b'b', 0)]) == [b'a', b'b']


def test_equal_messages_are_kept_as_often_as_one_reader_took_them():
    # the same bytes published twice (a writer both readers match) and once more (a writer only reader 1 matches)
    assert written([(b'x', 0), (b'x', 0), (b'x', 1), (b'x', 1), (b'x', 1)]) == [b'x', b'x', b'x']


def test_a_copy_arriving_beyond_the_window_is_written_again():
    arrivals = [(b'late', 0), *((bytes([i]), 0) for i in range(3)), (b'late', 1)]
    assert written(arrivals, window=3).count(b'late') == 2
    assert written(arrivals, window=4).count(b'late') == 1
