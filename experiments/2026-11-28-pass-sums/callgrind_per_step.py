import subprocess, re, sys
# per step = (22-step run - 2-step run) / 20: Ir and LL misses (x 64 B) of the whole program and
# of the contact pass (contact_loop<..., true>) and force_gather (ForceGather::run), inclusive.
def parse(f):
    out = subprocess.run(['callgrind_annotate', '--inclusive=yes', '--threshold=100', f], capture_output=True, text=True).stdout
    ev = None
    res = {}
    for line in out.splitlines():
        if line.startswith('Events shown:'):
            ev = line.split(':')[1].split()
        m = re.match(r'\s*([\d,]+) \(.*?\)\s+(.*)', line)
        if not m or ev is None:
            continue
        nums = re.findall(r'([\d,]+) \(\s*[\d.]+%\)', line)
        vals = [int(x.replace(',', '')) for x in nums]
        name = line.split('  ')[-1] if '???:' not in line else line[line.index('???:'):]
        key = None
        if 'PROGRAM TOTALS' in line: key = 'total'
        elif name.startswith('???:void sandcell::(anonymous namespace)::contact_loop<') and ', true>(' in name: key = 'contact'
        elif name.startswith('???:sandcell::ForceGather::run('): key = 'gather'
        if key and key not in res:
            res[key] = dict(zip(ev, vals))
    return res
tag = sys.argv[1:]
for t in tag:
    a, b = parse(f'cg.{t}.22'), parse(f'cg.{t}.2')
    for k in ('total', 'contact', 'gather'):
        ir = (a[k]['Ir'] - b[k]['Ir']) / 20
        mb = ((a[k]['DLmr'] + a[k]['DLmw']) - (b[k]['DLmr'] + b[k]['DLmw'])) * 64 / 20 / 1e6
        d1 = ((a[k]['D1mr'] + a[k]['D1mw']) - (b[k]['D1mr'] + b[k]['D1mw'])) * 64 / 20 / 1e6
        print(f'{t:6s} {k:8s} Ir/step {ir/1e6:7.2f} M   LL traffic {mb:6.2f} MB   D1 misses x64 {d1:6.2f} MB')
