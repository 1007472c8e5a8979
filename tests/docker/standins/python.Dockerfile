# Stand-in for the official python:3.11-slim (which cannot be pulled here): Debian bookworm's
# own Python 3.11 with pip, as the official image has it (python, pip on the PATH, pip allowed
# to install into the system, the Python headers for builds).
FROM multion-standin/bookworm
RUN apt-get update \
    && apt-get install -y --no-install-recommends python3 python3-pip python3-venv python3-dev \
       ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && rm -f /usr/lib/python3.11/EXTERNALLY-MANAGED \
    && ln -s /usr/bin/python3 /usr/local/bin/python \
    && ln -s /usr/bin/pip3 /usr/local/bin/pip
# The build host's CA bundle (package indexes may be reached through a proxy that signs with it).
COPY ca-certificates.crt /etc/ssl/certs/ca-certificates.crt
ENV PIP_CERT=/etc/ssl/certs/ca-certificates.crt SSL_CERT_FILE=/etc/ssl/certs/ca-certificates.crt
CMD ["python3"]
