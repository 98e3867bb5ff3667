"""Per-step callgrind figures of dem-bench: (22-step run - 2-step run) / 20.

Usage: callgrind_per_step.py TAG...  (reads cg.TAG.22 and cg.TAG.2 in the current folder)
Prints instructions and last-level misses x 64 B (traffic to and from memory) of the whole
program, of the stepping contact pass (contact_loop<..., true>) and of ForceGather::run, inclusive.
"""
import re
import subprocess
import sys


def parse(path):
    out = subprocess.run(['callgrind_annotate', '--inclusive=yes', '--threshold=100', path],
                         capture_output=True, text=True, check=True).stdout
    events, found = None, {}
    for line in out.splitlines():
        if line.startswith('Events shown:'):
            events = line.split(':')[1].split()
            continue
        if events is None or not re.match(r'\s*[\d,]+ \(', line):
            continue
        values = [int(x.replace(',', '')) for x in re.findall(r'([\d,]+) \(\s*[\d.]+%\)', line)]
        name = line[line.index('???:'):] if '???:' in line else line
        key = None
        if 'PROGRAM TOTALS' in line:
            key = 'total'
        elif name.startswith('???:void sandcell::(anonymous namespace)::contact_loop<') and ', true>(' in name:
            key = 'contact'
        elif name.startswith('???:sandcell::ForceGather::run('):
            key = 'gather'
        if key and key not in found:
            found[key] = dict(zip(events, values))
    return found


for tag in sys.argv[1:]:
    long_run, short_run = parse(f'cg.{tag}.22'), parse(f'cg.{tag}.2')
    for key in ('total', 'contact', 'gather'):
        a, b = long_run[key], short_run[key]
        ir = (a['Ir'] - b['Ir']) / 20
        mb = ((a['DLmr'] + a['DLmw']) - (b['DLmr'] + b['DLmw'])) * 64 / 20 / 1e6
        print(f'{tag:8s} {key:8s} instructions/step {ir / 1e6:7.2f} M   to and from memory {mb:6.2f} MB')
