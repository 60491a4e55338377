// page-cache write throughput into ONE file: pwrite threads vs memcpy into a shared mapping
#define _GNU_SOURCE
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>
#include <stdatomic.h>
static size_t S, B = 8 << 20; static int T, fd; static char *map; static atomic_size_t next;
static double now(){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+t.tv_nsec*1e-9;}
static void *work(void *arg){ int mode=(int)(long)arg; char *src=malloc(B); memset(src,7,B);
  for(;;){ size_t i=atomic_fetch_add(&next,1); size_t at=i*B; if(at>=S) break; size_t n=S-at<B?S-at:B;
    if(mode==0){ size_t d=0; while(d<n){ ssize_t w=pwrite(fd,src+d,n-d,at+d); if(w<=0){perror("pwrite");exit(1);} d+=w; } }
    else memcpy(map+at,src,n); }
  free(src); return 0; }
int main(int c,char**v){ const char*path=v[1]; S=(size_t)(atof(v[2])*(1<<30)); int mode=atoi(v[3]); T=atoi(v[4]);
  double t0=now(); fd=open(path,O_RDWR|O_CREAT|O_TRUNC,0644); if(fallocate(fd,0,0,S)){perror("fallocate");return 1;}
  double t1=now();
  if(mode){ map=mmap(0,S,PROT_READ|PROT_WRITE,MAP_SHARED,fd,0); if(map==MAP_FAILED){perror("mmap");return 1;} if(mode==2) madvise(map,S,MADV_HUGEPAGE);}
  pthread_t th[256]; next=0; for(int i=0;i<T;i++) pthread_create(&th[i],0,work,(void*)(long)mode); for(int i=0;i<T;i++) pthread_join(th[i],0);
  double t2=now(); if(mode) munmap(map,S); close(fd); double t3=now();
  printf("%s mode=%s T=%d %.2f GiB: alloc %.3f s, write %.3f s, unmap+close %.3f s, total %.3f s = %.2f GiB/s\n",path,mode==0?"pwrite":mode==1?"mmap":"mmap+huge",T,S/1073741824.0,t1-t0,t2-t1,t3-t2,t3-t0,S/1073741824.0/(t3-t0));
  return 0; }
