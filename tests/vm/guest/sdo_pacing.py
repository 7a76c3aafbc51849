#!/usr/bin/python3
"""The SDO pacing as candump sees it in the guest (gateway.sh). Reads a candump -L file of the
sub-devices' bus and prints "REQUESTS SHORT SPAN2_US SPAN10_US MEDIAN_US":
  * REQUESTS: the SDO initiate requests on 600h..67Fh (ccs 1 download, 2 upload, 5/6 block with
    cs 0: a transfer's segments follow their answers and are not paced);
  * SHORT: how many times three consecutive requests lie within less than GAP_US; SPAN2_US: the
    shortest span of two consecutive gaps.
    Why two gaps and not one: the pacer lets request k+1 start GAP_US after request k by the
    gateway's clock (canopen/301/sdo_pacer.hpp), and a stamp is the moment of the write, which
    is never before the time it was decided at. A write may lag its decision (a stall of the
    guest, a long wake-up), so two requests may stand close on the wire. Three need paced
    decisions to pile up during a lag: a request started on an answer is paced by that answer's
    reception time, so after the gateway lagged, requests decided a gap apart by those times
    leave in one wake-up. Rare when paced; without pacing the boot's parallel configurations
    send requests microseconds apart all the time;
  * SPAN10_US: the shortest span of 10 consecutive gaps, a figure only (a lagging write shortens
    it by the lag: no bound on it holds in a TCG guest);
  * MEDIAN_US: the median gap between consecutive requests.
    sdo_pacing.py DUMP [GAP_US]
"""
import sys

from hostlib import read_frames


def is_request(can_id, data):
    if not 0x600 <= can_id <= 0x67F or len(data) < 2:
        return False
    b = int(data[:2], 16)
    c = b >> 5
    return c in (1, 2) or (c == 5 and b % 4 == 0) or (c == 6 and b % 2 == 0)


def main():
    gap_us = float(sys.argv[2]) if len(sys.argv) > 2 else 1271
    t = [stamp for stamp, _, can_id, data in read_frames(sys.argv[1]) if is_request(can_id, data)]

    def spans(n):
        return [(t[k] - t[k - n]) * 1e6 for k in range(n, len(t))]

    span2 = spans(2)
    short = sum(1 for s in span2 if s < gap_us)
    gaps = sorted(spans(1))
    median = gaps[len(gaps) // 2] if gaps else -1
    print(len(t), short, round(min(span2, default=-1)), round(min(spans(10), default=-1)), round(median))


if __name__ == "__main__":
    main()
